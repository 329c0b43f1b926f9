"""Every ``--help`` of ``roco`` reads well at 80 columns: no markup left literal
(reStructuredText ````x````, Markdown ```x``` or ``**x**``, rich ``[tag]``), no word cut at a
line's end, the command table one short sentence per command, the overview's examples aligned.

Each help is rendered twice, at 80 columns and at 400: a word the narrow rendering shows must
be a word of the wide one (a word cut in two, or shortened with an ellipsis, is not).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from services.cli import app

ROOT = Path(__file__).resolve().parents[2]
BOX = "│╭╮╰╯─┃━┏┓┗┛"
LITERAL_MARKUP = [
    re.compile(r"``"),  # reStructuredText literal
    re.compile(r"`"),  # Markdown code span left unrendered
    re.compile(r"\*\*"),  # Markdown strong
    re.compile(r":(class|func|meth|mod|data|attr):"),  # Sphinx roles
    re.compile(r"\[/?(bold|dim|red|green|yellow|cyan|magenta|italic|b|i)\]"),  # rich markup tags
    re.compile(r"\x08"),  # click's \b paragraph marker
]


def command_paths() -> list[tuple[str, ...]]:
    """Every command and group of ``roco``, the root included: ``()``, ``("run",)``, …"""
    paths: list[tuple[str, ...]] = []

    def walk(command: object, path: tuple[str, ...]) -> None:
        paths.append(path)
        for name, sub in sorted(getattr(command, "commands", {}).items()):
            walk(sub, (*path, name))

    walk(typer.main.get_command(app), ())
    return paths


def render(path: tuple[str, ...], columns: int) -> str:
    result = CliRunner().invoke(app, [*path, "--help"], env={"COLUMNS": str(columns)}, prog_name="roco")
    assert result.exit_code == 0, result.output
    return result.output


def words(text: str) -> list[str]:
    return [w for line in text.splitlines() for w in line.strip(BOX + " ").split() if w.strip(BOX)]


PATHS = command_paths()


def test_the_walk_finds_every_command() -> None:
    names = {" ".join(p) for p in PATHS}
    assert {"", "run", "scenario", "chaos", "doctor", "spec verify", "fault kill", "deploy certs"} <= names


@pytest.mark.parametrize("path", PATHS, ids=lambda p: " ".join(p) or "roco")
def test_help_has_no_literal_markup_and_no_word_cut(path: tuple[str, ...]) -> None:
    narrow = render(path, 80)
    assert max(len(line) for line in narrow.splitlines()) <= 80
    for pattern in LITERAL_MARKUP:
        assert not pattern.search(narrow), (pattern.pattern, narrow)
    wide = set(words(render(path, 400)))
    cut = [w for w in words(narrow) if w not in wide]
    assert not cut, (cut, narrow)


@pytest.mark.parametrize("path", PATHS, ids=lambda p: " ".join(p) or "roco")
def test_help_reads_the_same_wherever_the_checkout_is(path: tuple[str, ...]) -> None:
    """A default shown as an absolute path grows with the checkout's location and is cut in a
    deeper one (CI checks out elsewhere than a developer)."""
    assert str(ROOT) not in render(path, 400)


def test_the_word_check_catches_a_cut_word() -> None:
    wide = set(words("│ --services  every agent: a_hi,a_co,a_pl │"))
    assert [w for w in words("│ a_hi,a_co,a_… │") if w not in wide] == ["a_hi,a_co,a_…"]


def _panel_rows(text: str, title: str) -> list[str]:
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"╭─ {title}"))
    end = next(i for i in range(start, len(lines)) if lines[i].startswith("╰"))
    return [line.strip("│ ") for line in lines[start + 1 : end]]


@pytest.mark.parametrize("path", [p for p in PATHS if p in {(), ("spec",), ("fault",), ("deploy",)}])
def test_the_command_table_is_one_short_sentence_per_command(path: tuple[str, ...]) -> None:
    """At 100 columns every command's line fits on one row and ends its sentence."""
    rows = _panel_rows(render(path, 100), "Commands")
    assert rows
    for row in rows:
        _name, _, sentence = row.partition(" ")
        assert sentence.strip().endswith((".", ")")), row


def test_the_overview_aligns_its_examples_and_shows_defaults_rich_mode_ate() -> None:
    text = render((), 80)
    examples = [
        line for line in text.splitlines() if line.strip().startswith("roco ") and "  " in line.strip()
    ]
    assert len(examples) >= 4
    # the explanation column starts at the same place on every example line
    starts = {re.search(r"\S\s{2,}(\S)", line).start(1) for line in examples}  # type: ignore[union-attr]
    assert len(starts) == 1, examples
    # "[default: on, unless ROCO_ACL=0]" was taken for a rich markup tag and vanished
    assert "ROCO_ACL=0" in " ".join(words(render(("run",), 80)))


def test_the_root_offers_shell_completion() -> None:
    text = render((), 80)
    assert "--install-completion" in text and "--show-completion" in text


def test_bash_and_zsh_complete_command_names() -> None:
    runner = CliRunner()
    bash = runner.invoke(
        app,
        [],
        env={"_ROCO_COMPLETE": "complete_bash", "COMP_WORDS": "roco sc", "COMP_CWORD": "1"},
        prog_name="roco",
    )
    assert bash.output.split() == ["scenario"]
    zsh = runner.invoke(
        app,
        [],
        env={"_ROCO_COMPLETE": "complete_zsh", "_TYPER_COMPLETE_ARGS": "roco spec ver"},
        prog_name="roco",
    )
    assert '"verify":' in zsh.output and '"verify-code":' in zsh.output and '"show":' not in zsh.output
    for shell, marker in (
        ("bash", "complete -o default -F _roco_completion roco"),
        ("zsh", "compdef _roco_completion roco"),
    ):
        script = runner.invoke(app, [], env={"_ROCO_COMPLETE": f"source_{shell}"}, prog_name="roco")
        assert marker in script.output
