"""services/cli.py only assembles the tools' Typer apps (docs/README.md, "Where a new command
goes"): every command of ``roco`` is defined in a ``cli`` module of its tool's package, and
services/cli.py stays short."""

from __future__ import annotations

from pathlib import Path

import typer

from services.cli import app

ROOT = Path(__file__).resolve().parents[2]
MOST_LINES = 300


def commands(command: object, path: tuple[str, ...] = ()) -> list[tuple[str, str]]:
    """``(command path, module of its callback)`` of every command below ``command``."""
    found: list[tuple[str, str]] = []
    for name, sub in getattr(command, "commands", {}).items():
        callback = getattr(sub, "callback", None)
        if callback is not None and not hasattr(sub, "commands"):
            found.append((" ".join((*path, name)), callback.__module__))
        found += commands(sub, (*path, name))
    return found


def test_every_command_is_defined_in_its_tools_cli_module() -> None:
    found = commands(typer.main.get_command(app))
    assert len(found) > 40
    misplaced = [
        (name, module)
        for name, module in found
        if not (module.count(".") == 2 and module.startswith("services.") and module.endswith("cli"))
    ]
    assert misplaced == []


def test_the_assembler_is_short() -> None:
    assert len((ROOT / "services" / "cli.py").read_text().splitlines()) < MOST_LINES
