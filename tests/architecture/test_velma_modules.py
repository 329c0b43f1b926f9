"""velma/'s modules import one another without a circle: every ``import`` of a velma module
counts, at module level, inside functions and under ``TYPE_CHECKING`` (a type-only circle
still ties the modules' meanings together)."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.architecture.test_import_graph import ROOT, cycles


def velma_modules() -> dict[str, Path]:
    """Module name (``velma.executor.state``) → its file, for every module under velma/."""
    return {
        ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__"): p
        for p in (ROOT / "velma").rglob("*.py")
    }


def module_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Module → the other modules of ``modules`` it imports (``from a.b import c`` imports
    ``a.b``, or ``a.b.c`` when that is a module)."""
    edges: dict[str, set[str]] = {}
    for module, path in modules.items():
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            found.update(n for n in names if n in modules and n != module)
        edges[module] = found
    return edges


def test_velma_modules_import_one_another_without_a_circle() -> None:
    assert cycles(module_graph(velma_modules())) == set()


def test_a_type_only_import_inside_a_function_closes_a_circle(tmp_path: Path) -> None:
    """The graph counts imports under ``TYPE_CHECKING`` and inside functions."""
    (tmp_path / "a.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import m.b\n")
    (tmp_path / "b.py").write_text("def f() -> None:\n    from m.a import x\n")
    (tmp_path / "c.py").write_text("import m.a\n")
    modules = {f"m.{n}": tmp_path / f"{n}.py" for n in "abc"}
    assert cycles(module_graph(modules)) == {frozenset({"m.a", "m.b"})}
