"""No import circle among the modules of services/runtime: each module imports only modules
that do not import it back, directly or through others. Every ``import`` of a runtime module
counts: at module level, under ``TYPE_CHECKING`` and inside functions (an import inside a
function hides a circle from Python, not from a reader). A package's ``__init__`` is a module
of its own (``services.runtime.roles``); that a submodule's import first runs its package's
``__init__`` is Python's, not an edge.
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.architecture.test_import_graph import cycles

ROOT = Path(__file__).resolve().parents[2]
RUNTIME = "services.runtime"


def module_graph(root: Path, package: str) -> dict[str, set[str]]:
    """Module → the modules of ``package`` (under ``root``) it imports, anywhere in its source."""
    base = root.joinpath(*package.split("."))
    modules = {
        ".".join(p.relative_to(root).with_suffix("").parts).removesuffix(".__init__"): p
        for p in base.rglob("*.py")
    }
    edges: dict[str, set[str]] = {}
    for module, path in modules.items():
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names: list[str] = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                # ``from pkg import sub``: the submodule when there is one, else the package
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    names.append(sub if sub in modules else node.module)
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            targets |= {n for n in names if n in modules and n != module}
        edges[module] = targets
    return edges


def test_the_runtime_modules_import_no_circle() -> None:
    found = cycles(module_graph(ROOT, RUNTIME))
    assert found == set(), "import circles in services/runtime: " + "; ".join(
        " ↔ ".join(sorted(c)) for c in found
    )


def test_a_circle_hidden_inside_a_function_is_found(tmp_path: Path) -> None:
    """The planted fault: ``low`` imports ``top`` inside a function, ``top`` imports ``low``
    at module level (as roles.py once imported agent.py's ``Received``)."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "top.py").write_text("from pkg.low import f\n")
    (pkg / "low.py").write_text("def f():\n    from pkg.top import g\n    return g\n")
    (pkg / "alone.py").write_text("from pkg import low\n")
    assert cycles(module_graph(tmp_path, "pkg")) == {frozenset({"pkg.top", "pkg.low"})}


def test_a_circle_under_type_checking_is_found(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.b import B\n"
    )
    (pkg / "b.py").write_text("import pkg.a\n")
    assert cycles(module_graph(tmp_path, "pkg")) == {frozenset({"pkg.a", "pkg.b"})}
