"""The walk-through of docs/spec.md ("adding an agent"), stage by stage: its TOML snippets
are read from the document itself and added to a copy of the shipped specification, and the
tools say what the document says they say."""

from __future__ import annotations

import re
from pathlib import Path

from services.spec.check import check_report
from services.spec.model import DEFAULT_SPEC
from services.spec_check.code_check import verify_code_report

DOC = Path(__file__).resolve().parents[2] / "docs" / "spec.md"


def snippet(n: int) -> str:
    m = re.search(rf"```toml walkthrough-{n}\n(.*?)```", DOC.read_text(), re.S)
    assert m, f"docs/spec.md lost walk-through snippet {n}"
    return m.group(1)


def stage(tmp_path: Path, *parts: str, edits: dict[str, str] | None = None) -> Path:
    text = DEFAULT_SPEC.read_text()
    for old, new in (edits or {}).items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / "spec.toml"
    # requirements and steps before the agents, as in the shipped file
    head, tail = text.split("\n[[agents]]", 1)
    decomposition = "\n".join(p for p in parts if "[[steps]]" in p or "[[requirements]]" in p)
    rest = "\n".join(p for p in parts if p not in decomposition)
    path.write_text(head + "\n" + decomposition + "\n[[agents]]" + tail + "\n" + rest)
    return path


def test_stage_1_a_new_step_makes_check_list_what_is_missing(tmp_path: Path) -> None:
    ok, text = check_report(stage(tmp_path, snippet(1)))
    assert not ok
    for line in (
        "stop condition: group 'ui' of the final fringe is substituted by no agent",
        "stop condition: group 'lb' of the final fringe is substituted by no agent",
        "agent a_hi substitutes group 'hi', which is not in the final fringe",
        "channel C2 joins <group ui> and a_co by the decomposition, but a_co and a_hi in [[channels]]",
        "channel C7 of the decomposition is not specified in [[channels]]",
        "5 problem(s)",
    ):
        assert line in text, text


def test_stage_2_the_spec_conforms_but_the_code_does_not(tmp_path: Path) -> None:
    path = stage(tmp_path, snippet(1), snippet(2), edits={'group = "hi"': 'group = "ui"'})
    ok, text = check_report(path)
    assert ok, text
    ok, text = verify_code_report(path)
    assert not ok
    assert "a_lb may receive request from a_hi on C7 (fipa-request) but no code in" in text
    assert "a_lb may receive cancel from a_hi on C7 (fipa-request) but no code in" in text


def test_stage_3_the_finished_agent_conforms(tmp_path: Path) -> None:
    two = snippet(2).replace("logbook_v1", "logbook_v2")
    path = stage(tmp_path, snippet(1), two, edits={'group = "hi"': 'group = "ui"'})
    assert check_report(path)[0]
    ok, text = verify_code_report(path)
    assert ok, text
