"""Every command of ``roco`` is defined in services/cli/<its name>.py (docs/README.md, "Where a
new command goes"): the module of a command's callback is ``services.cli.<name>``, ``name``
the command's first word (``spec new-agent``: services/cli/spec.py), or a module of
services/cli/ whose docstring declares the command in its head (``roco send`` and ``roco
disturb``: …). services/cli/__init__.py only assembles their apps and stays short; imports
point down: no tool imports services/cli/, and only services/cli/ imports typer."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import typer

from services.cli import app
from tests.architecture.test_import_graph import TOPS, import_graph

ROOT = Path(__file__).resolve().parents[2]
MOST_LINES = 120
DECLARED = re.compile(r"``roco ([\w-]+)")
"""A command a module's docstring names in its head (before its first colon)."""


def commands(command: object, path: tuple[str, ...] = ()) -> list[tuple[str, str]]:
    """``(command path, module of its callback)`` of every command below ``command``."""
    found: list[tuple[str, str]] = []
    for name, sub in getattr(command, "commands", {}).items():
        callback = getattr(sub, "callback", None)
        if callback is not None and not hasattr(sub, "commands"):
            found.append((" ".join((*path, name)), callback.__module__))
        found += commands(sub, (*path, name))
    return found


def declared(module: str) -> set[str]:
    """The commands ``module``'s docstring declares in its head: ``roco send`` and ``roco
    disturb`` in ````roco send`` and ``roco disturb``: …``."""
    doc = importlib.import_module(module).__doc__ or ""
    return set(DECLARED.findall(doc.split(":", 1)[0]))


def misplaced(found: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """The commands of ``found`` not defined in services/cli/<their first word>.py (nor in a
    module of services/cli/ that declares them)."""
    wrong = []
    for name, module in found:
        first = name.split()[0]
        home = f"services.cli.{first.replace('-', '_')}"
        below = module.startswith("services.cli.") and module.count(".") == 2
        if not (module == home or (below and first in declared(module))):
            wrong.append((name, module))
    return wrong


def test_every_command_is_defined_in_services_cli_under_its_name() -> None:
    found = commands(typer.main.get_command(app))
    assert len(found) > 40
    assert misplaced(found) == []


def planted() -> None:
    """A command defined outside services/cli/ (this test module)."""


def test_a_command_defined_elsewhere_is_found() -> None:
    elsewhere = typer.Typer()
    elsewhere.command("run")(planted)
    group = typer.Typer()
    group.command("names")(planted)
    elsewhere.add_typer(group, name="spec")
    found = commands(typer.main.get_command(elsewhere))
    assert misplaced(found) == [("run", __name__), ("spec names", __name__)]
    assert misplaced([("disturb", "services.cli.run"), ("spec x", "services.cli.spec")]) == [
        ("disturb", "services.cli.run")
    ]


def test_the_assembler_is_short() -> None:
    assert len((ROOT / "services" / "cli" / "__init__.py").read_text().splitlines()) < MOST_LINES


def test_no_tool_imports_the_cli() -> None:
    graph = import_graph()
    assert [p for p, imported in sorted(graph.items()) if "services.cli" in imported] == []


def test_only_the_cli_imports_typer() -> None:
    found = []
    for top in TOPS:
        for path in (ROOT / top).rglob("*.py"):
            if path.is_relative_to(ROOT / "services" / "cli"):
                continue
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
                if isinstance(node, ast.ImportFrom) and node.module:
                    names = [node.module]
                if any(n == "typer" or n.startswith("typer.") for n in names):
                    found.append(path.relative_to(ROOT).as_posix())
    assert found == []
