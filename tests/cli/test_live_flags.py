"""`roco run` / `roco scenario` exit 1 with one `roco:` line naming a requirement the live
monitor flagged during the run (services/recorder/flags.py), even when the run went as
expected; `roco status` lists the flags the traffic recorder answers with. A run folder with a
planted flag, no fleet."""

from __future__ import annotations

from pathlib import Path

import pytest
import typer

from services.cli.run import exit_on_failure
from services.cli.status import _flag_lines
from services.recorder.flags import FlagsReply, append_flag
from tests.support.flags import a_flag

FLAG = a_flag()


def test_a_flag_makes_a_run_that_went_well_exit_1_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    exit_on_failure("", True, "the task succeeded", tmp_path)  # no flag: no exit
    append_flag(tmp_path, FLAG)
    with pytest.raises(typer.Exit) as ended:
        exit_on_failure("", True, "the task succeeded", tmp_path)
    assert ended.value.exit_code == 1
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(
        "roco: requirement R3.3 violated during the run: R3.3 “p”: C1 a_ta → a_co inform at "
    )
    assert line.endswith(f"(w) (run folder {tmp_path})")
    with pytest.raises(typer.Exit):
        exit_on_failure("s", False, "#1 failed", tmp_path)
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("roco: scenario “s” did not go as expected: #1 failed; requirement R3.3 violated")


def test_status_lists_the_flags_the_recorder_answered_with() -> None:
    """One line per flag; how many more when the answer was capped; one line when no recorder
    answered (tests/recorder/test_flags_query.py asks a real recorder)."""
    assert _flag_lines(FlagsReply(flags=[], total=0)) == []
    assert _flag_lines(FlagsReply(flags=[FLAG], total=1)) == [f"violated  {FLAG.line()}"]
    assert _flag_lines(FlagsReply(flags=[FLAG], total=3))[1:] == [
        "violated  (and 2 more in the run folder's flags.jsonl)"
    ]
    assert _flag_lines(None) == ["flags     (the recorder did not answer: live requirement flags unknown)"]
