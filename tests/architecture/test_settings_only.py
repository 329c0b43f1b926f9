"""shared/settings.py is the only module that spells a ``ROCO_*`` variable, every variable it
declares is documented, and docs/settings.md is what it renders.

The scan parses (``ast``) every ``.py`` under ``shared/``, ``services/``, ``velma/`` and
``scripts/``: a string constant that starts with ``ROCO_`` (an f-string's text too) or a
keyword argument named ``ROCO_…`` outside shared/settings.py fails, named by file and line.
Docstrings and comments may name variables (prose); so may text that does not start with
one (a help text's ``[default: ROCO_ROUTER]``).
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import msgspec

from shared.settings import DEPLOYMENT, PREFIX, Settings, names, variables
from shared.settings_markdown import markdown

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("shared", "services", "velma", "scripts")
SETTINGS = ROOT / "shared" / "settings.py"
DOC = ROOT / "docs" / "settings.md"
ANY_NAME = r"\b(ROCO_[A-Z0-9_]+)"
READ_BY_DEPLOYMENT = {
    ROOT / "deploy" / "compose.yaml": ANY_NAME,
    ROOT / "deploy" / "entrypoint.sh": ANY_NAME,
    ROOT / "setup.py": r"environ\.get\(\"(ROCO_[A-Z0-9_]+)\"",  # not its C macros (ROCO_WITH_MUJOCO)
}
"""Files outside the scan whose ``ROCO_*`` variables must be declared too, and how each names one."""


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the string constants that are docstrings: a module's, class's or function's
    first statement, and any other string standing alone as a statement (an attribute's)."""
    return {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr)
        and isinstance(node.value, ast.Constant)
        and isinstance(node.value.value, str)
    }


def spelled(source: str, where: str) -> list[str]:
    """``where:line: text`` for each ``ROCO_*`` name ``source`` spells in code (module
    docstring)."""
    tree = ast.parse(source, where)
    prose = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in prose:
            if node.value.startswith(PREFIX):
                found.append(f"{where}:{node.lineno}: {node.value[:60]!r}")
        elif isinstance(node, ast.keyword) and node.arg is not None and node.arg.startswith(PREFIX):
            found.append(f"{where}:{node.lineno}: {node.arg}=")
    return found


def _sources() -> list[Path]:
    return [p for top in SCANNED for p in sorted((ROOT / top).rglob("*.py")) if p != SETTINGS]


def test_no_module_but_shared_settings_spells_a_roco_variable() -> None:
    found = [line for p in _sources() for line in spelled(p.read_text(), str(p.relative_to(ROOT)))]
    assert not found, "ROCO_* spelled outside shared/settings.py (use Settings.env_name):\n" + "\n".join(
        found
    )


def test_the_scan_finds_a_spelled_variable_and_leaves_prose_alone() -> None:
    source = '''"""Reads ROCO_SEED (prose)."""
import os
X = "ROCO_SEED"
"""An attribute's docstring may say ROCO_SEED too."""
def f() -> str:
    """ROCO_RUN_DIR, in a docstring."""
    env = dict(os.environ, ROCO_TLS="1")  # a comment: ROCO_ACL
    help = "default: ROCO_ROUTER"
    return f"ROCO_PERCEPTION={env}"
'''
    assert spelled(source, "planted.py") == [
        "planted.py:3: 'ROCO_SEED'",
        "planted.py:7: ROCO_TLS=",
        "planted.py:9: 'ROCO_PERCEPTION='",
    ]


def test_every_setting_is_declared_with_a_name_a_type_a_default_and_a_doc() -> None:
    declared = variables()
    assert len(declared) >= 30
    fields = msgspec.structs.fields(Settings)
    assert [f.name for f in fields] == list(declared)
    for f in fields:
        v = declared[f.name]
        assert f.default is not msgspec.NODEFAULT and f.default_factory is msgspec.NODEFAULT, f.name
        assert v.default == f.default == getattr(Settings(), f.name), f.name
        assert v.name.startswith(PREFIX) and re.fullmatch(r"ROCO_[A-Z0-9_]+", v.name), v.name
        assert v.kind.strip() and v.doc.strip() and "\n" not in v.doc, v.name
    for d in DEPLOYMENT:
        assert re.fullmatch(r"ROCO_[A-Z0-9_]+", d.name) and d.doc.strip(), d.name
    assert len(set(names())) == len(names()), "a variable is declared twice"


def test_each_default_reads_back_as_itself() -> None:
    """What the docs and ``roco doctor`` show as a default, set in the environment, gives the
    default: the declared type, its reading and its default agree."""
    from shared.settings import env_text

    for field, v in variables().items():
        text = env_text(v.default)
        if text:
            got = getattr(Settings.from_env({v.name: text}, only=(field,)), field)
            assert got == v.default or (math.isinf(got) and math.isinf(v.default)), field


def test_every_field_the_code_names_is_declared() -> None:
    """``Settings.env_name("x")`` and ``only=("x", …)`` in the code name fields that exist (a
    typo would raise KeyError only when that line runs)."""
    declared = set(variables())
    unknown = []
    for p in _sources():
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            named: list[ast.expr] = []
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                if node.func.attr == "env_name":
                    named = list(node.args)
                named += [
                    e
                    for k in node.keywords
                    if k.arg == "only" and isinstance(k.value, ast.Tuple | ast.List)
                    for e in k.value.elts
                ]
            for arg in named:
                if isinstance(arg, ast.Constant) and arg.value not in declared:
                    unknown.append(f"{p.relative_to(ROOT)}:{arg.lineno}: {arg.value!r}")
    assert not unknown, "fields shared/settings.py does not declare:\n" + "\n".join(unknown)


def test_the_deployment_files_read_only_declared_variables() -> None:
    declared = set(names())
    from services.deploy.compose import HEAD, VIEWER

    texts = {str(p.relative_to(ROOT)): (p.read_text(), how) for p, how in READ_BY_DEPLOYMENT.items()}
    texts["services/deploy/compose.py"] = (HEAD + VIEWER, ANY_NAME)
    for where, (text, how) in texts.items():
        used = set(re.findall(how, text))
        assert used, where
        assert used <= declared, (where, sorted(used - declared))


def test_docs_settings_md_is_what_the_declarations_render() -> None:
    """Regenerate with ``python -m shared.settings_markdown > docs/settings.md``."""
    assert DOC.read_text() == markdown(), (
        "docs/settings.md is stale: python -m shared.settings_markdown > docs/settings.md"
    )
    assert all(f"`{n}`" in DOC.read_text() for n in names())
