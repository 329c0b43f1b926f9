"""The tests that check each requirement, found without running them.

A test names the requirement it checks with a pytest marker (registered in pyproject.toml)::

    @pytest.mark.requirement("R1.2")
    def test_the_more_urgent_command_runs_first() -> None: ...

on a test function, on a ``Test*`` class (each of its ``test_*`` methods), or for a whole
module (``pytestmark = pytest.mark.requirement("R3.1")``, alone or in a list). Several ids may
be given in one marker. :func:`marked_tests` reads every ``test_*.py`` under a folder with
:mod:`ast`, runs nothing, and checks each id against the specification's requirements: an
unknown id, or an argument that is not a string literal, is a :class:`MarkError`.
"""

from __future__ import annotations

import ast
from collections.abc import Collection, Iterator
from dataclasses import dataclass
from pathlib import Path

TESTS = Path(__file__).resolve().parents[2] / "tests"
"""The project's test folder."""
MARKER = "requirement"
"""The marker's name: ``pytest.mark.requirement``."""
MAX_TEST_FILE = 2_000_000
"""Bytes: a test file larger than this is refused (:class:`MarkError`), not read."""


class MarkError(ValueError):
    """A marker that names no requirement of the specification, or that cannot be read; the
    message names the file and line (``tests/x.py:12: …``)."""


@dataclass(frozen=True)
class MarkedTest:
    """One test that names requirements: its pytest node id (``tests/a/test_b.py::test_c``,
    relative to the folder above ``tests``), the line it is defined on, and the ids."""

    node: str
    line: int
    requirements: tuple[str, ...]


def marked_tests(folder: Path, known: Collection[str]) -> list[MarkedTest]:
    """Every test under ``folder`` (``test_*.py``, recursively, in path order) that carries
    the marker, with the requirement ids it names. Raises MarkError for an id not in
    ``known`` or a marker argument that is not a string literal, and for a test file that
    is not Python or is larger than :data:`MAX_TEST_FILE`. A folder that does not exist has
    no tests."""
    found: list[MarkedTest] = []
    base = folder.resolve().parent
    for path in sorted(folder.rglob("test_*.py")):
        where = path.resolve().relative_to(base).as_posix()
        found += _file_tests(_parse(path, where), where, set(known))
    return found


def by_requirement(tests: list[MarkedTest]) -> dict[str, list[str]]:
    """Requirement id → the node ids of the tests that name it, in the order found."""
    out: dict[str, list[str]] = {}
    for t in tests:
        for rid in t.requirements:
            out.setdefault(rid, []).append(t.node)
    return out


def _parse(path: Path, where: str) -> ast.Module:
    if path.stat().st_size > MAX_TEST_FILE:
        raise MarkError(f"{where}: larger than {MAX_TEST_FILE} bytes, not read")
    try:
        return ast.parse(path.read_bytes(), where)
    except (SyntaxError, ValueError) as exc:
        raise MarkError(f"{where}: not Python: {exc}") from None


def _file_tests(module: ast.Module, where: str, known: set[str]) -> list[MarkedTest]:
    """The marked tests of one module: its own marks apply to every test in it."""
    everywhere: tuple[str, ...] = ()
    for node in module.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "pytestmark" for t in node.targets
        ):
            marks = node.value.elts if isinstance(node.value, ast.List | ast.Tuple) else [node.value]
            everywhere += _ids(marks, where, known)
    out = []
    for node, prefix, inherited in _tests(module, where, known):
        ids = everywhere + inherited + _ids(node.decorator_list, where, known)
        if ids:
            out.append(MarkedTest(f"{where}::{prefix}{node.name}", node.lineno, tuple(dict.fromkeys(ids))))
    return out


def _tests(
    module: ast.Module, where: str, known: set[str]
) -> Iterator[tuple[ast.FunctionDef | ast.AsyncFunctionDef, str, tuple[str, ...]]]:
    """The module's test functions and ``Test*`` classes' test methods: (function, node id
    prefix, the ids its class's own marker names)."""
    for node in module.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name.startswith("test"):
            yield node, "", ()
        elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            inherited = _ids(node.decorator_list, where, known)
            for item in node.body:
                if isinstance(item, ast.FunctionDef | ast.AsyncFunctionDef) and item.name.startswith("test"):
                    yield item, f"{node.name}::", inherited


def _ids(marks: list[ast.expr], where: str, known: set[str]) -> tuple[str, ...]:
    """The requirement ids named by the marker among ``marks``; checked against ``known``."""
    ids = []
    for call in _calls(marks):
        for arg in call.args:
            if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
                raise MarkError(f"{where}:{call.lineno}: pytest.mark.{MARKER} takes string literals")
            if arg.value not in known:
                raise MarkError(f"{where}:{call.lineno}: unknown requirement {arg.value!r}")
            ids.append(arg.value)
    return tuple(ids)


def _calls(marks: list[ast.expr]) -> Iterator[ast.Call]:
    """The ``….mark.requirement(…)`` calls among ``marks``."""
    for mark in marks:
        if (
            isinstance(mark, ast.Call)
            and isinstance(mark.func, ast.Attribute)
            and mark.func.attr == MARKER
            and _is_mark(mark.func.value)
        ):
            yield mark


def _is_mark(node: ast.expr) -> bool:
    """``pytest.mark`` (any ``….mark``) or ``mark`` imported from pytest."""
    return (isinstance(node, ast.Attribute) and node.attr == "mark") or (
        isinstance(node, ast.Name) and node.id == "mark"
    )
