"""Every import of one of roco's own modules names a module that exists: a module moved without
its importers updated fails here, not when a fleet first reaches the import (mypy reports it
too: pyproject.toml's override for roco's packages)."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OWN = ("shared", "services", "velma", "tests")


def imported_modules(source: str) -> set[str]:
    """The modules of roco's packages (:data:`OWN`) that ``source`` imports, absolute imports
    only (``from a.b import c``: ``a.b``)."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        found |= {n for n in names if n.split(".")[0] in OWN}
    return found


def missing(root: Path) -> list[str]:
    """``path: module`` for each import under ``root`` of a module that cannot be found."""
    out = []
    for folder in (*OWN, "scripts"):
        for path in sorted((root / folder).rglob("*.py")):
            for module in sorted(imported_modules(path.read_text())):
                if importlib.util.find_spec(module) is None:
                    out.append(f"{path.relative_to(root)}: {module}")
    return out


def test_every_own_import_names_a_module_that_exists() -> None:
    assert missing(ROOT) == []


def test_an_import_of_a_moved_module_is_found(tmp_path: Path) -> None:
    (tmp_path / "services").mkdir()
    (tmp_path / "services" / "m.py").write_text(
        "from services.report.gone_module import f\nimport services.runtime.keys\nfrom . import x\n"
    )
    assert missing(tmp_path) == ["services/m.py: services.report.gone_module"]
