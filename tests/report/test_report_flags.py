"""The requirements the live monitor flagged during a run (services/recorder/flags.py) in its
report: under the requirements' table, each with its event and its time since the run start;
a run without flags has no such lines; a flag file cut short loses only its cut line."""

from __future__ import annotations

from pathlib import Path

from services.recorder.flags import FLAGS_JSONL, LiveFlag, append_flag
from services.report import build_report, write_report
from tests.report.conftest import STARTED

FLAG = LiveFlag(
    requirement="R3.3",
    prop="a plan cancelled while a_ta holds the jar: the jar put down, then Preempted",
    event="C1 a_ta → a_co inform SWStatus state=Preempted (conversation c-exec1)",
    why="… came while waiting for C6 …",
    t=STARTED + 21.25,
    seq=132,
    recorded=133,
    flagged=STARTED + 21.3,
)


def test_a_flag_is_shown_beside_the_requirements(run_dir: Path) -> None:
    assert build_report(run_dir).flags == []
    assert "Flagged violated during the run" not in write_report(run_dir).read_text()
    append_flag(run_dir, FLAG)
    with (run_dir / FLAGS_JSONL).open("ab") as f:
        f.write(b'{"requirement": "R')  # a recorder killed mid-write
    assert build_report(run_dir).flags == [FLAG]
    text = write_report(run_dir).read_text()
    assert "Requirements traced to this run" in text and "Flagged violated during the run" in text
    assert f"- **violated** R3.3 “{FLAG.prop}”: {FLAG.event} at 21.2 s ({FLAG.why})" in text
