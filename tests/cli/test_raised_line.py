"""`roco run`'s last line names what the agents raised (their handler and behaviour errors,
the agents that exited by themselves: services/runtime/raised.py), and `roco run` / `roco
scenario` then exit 1 with one `roco:` line even when the task succeeded. A run folder with
planted counters, no fleet."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import typer

from services.cli.report import finish_report
from services.cli.run import exit_on_failure
from services.runtime.run_folder import RunInfo, write_run_info

RAISED = "2 handler errors in a_ta: see logs/a_ta.log"


def _info(**kw: object) -> RunInfo:
    now = time.time()
    return RunInfo(started=now - 12.0, ended=now, succeeded=True, commands=["pour"], **kw)  # type: ignore[arg-type]


def test_the_last_line_names_the_errors_and_the_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    info = _info(raised={"a_ta": {"handler_errors": 2}})
    write_run_info(tmp_path, info)
    finish_report(tmp_path, info)
    line = capsys.readouterr().out.splitlines()[-1]
    assert line.startswith("roco: succeeded in 12.0 s wall; 2 handler errors in a_ta: see logs/a_ta.log; ")
    assert "Agents raised | 2 handler errors in a_ta" in (tmp_path / "report.md").read_text()


def test_a_clean_run_says_nothing_of_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    info = _info()
    write_run_info(tmp_path, info)
    finish_report(tmp_path, info)
    line = capsys.readouterr().out.splitlines()[-1]
    assert line.startswith("roco: succeeded in 12.0 s wall; 0 communicates; "), line


def test_an_agent_that_raised_makes_a_run_that_went_well_exit_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    exit_on_failure("", True, "the task succeeded", tmp_path, "")  # nothing raised: no exit
    with pytest.raises(typer.Exit) as ended:
        exit_on_failure("", True, "the task succeeded", tmp_path, RAISED)
    assert ended.value.exit_code == 1
    (line,) = capsys.readouterr().err.splitlines()
    assert line == f"roco: agents raised: {RAISED} (run folder {tmp_path})"
