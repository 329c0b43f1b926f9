"""The report's header says what the agents raised (services/report/build.py): from run.json
when the run's runner kept it, else from the counters the run saved (``counters.json``); nothing
when the run folder has neither."""

from __future__ import annotations

from pathlib import Path

from services.report import build_report
from services.report.build import NOTHING_RAISED
from services.runtime.counters import CountersReport, save_counters
from services.runtime.run_folder import RunInfo, write_run_info


def _folder(tmp_path: Path, **kw: object) -> Path:
    (tmp_path / "logs").mkdir()
    write_run_info(tmp_path, RunInfo(started=1.0, **kw))  # type: ignore[arg-type]
    return tmp_path


def test_the_counters_a_run_saved_name_the_agent_that_raised(tmp_path: Path) -> None:
    run = _folder(tmp_path)
    assert build_report(run).header.raised == ""  # no counters: nothing said
    save_counters(run, {"a_ta": CountersReport("a_ta", 2.0, {"received.inform": 4, "behaviour_errors": 1})})
    assert build_report(run).header.raised == "1 behaviour error in a_ta: see logs/a_ta.log"
    save_counters(run, {"a_ta": CountersReport("a_ta", 2.0, {"received.inform": 4})})
    assert build_report(run).header.raised == NOTHING_RAISED


def test_run_json_keeps_errors_and_exits(tmp_path: Path) -> None:
    run = _folder(tmp_path, raised={"a_co": {"handler_errors": 3}}, crashed={"a_km": [70]})
    assert build_report(run).header.raised == (
        "3 handler errors in a_co: see logs/a_co.log; "
        "a_km exited (code 70) and was started again: see logs/a_km.log"
    )
