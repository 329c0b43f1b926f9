"""The scenario runner (services/scenario/runner.py, behind ``roco run`` and ``roco scenario``)
says what an agent tells the person unprompted — a_hi's ``notice`` report, which answers no
command of the run — with its sender, and keeps it for the run's summary."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from services.runtime.human import HumanReport, ReportKind
from services.scenario.model import Scenario, Step
from services.scenario.runner import SUMMARY_NOTICES, CommandRecord, ScenarioOutcome, ScenarioRunner

NOTICE = HumanReport(
    request_id="", kind=ReportKind.NOTICE, text="the jar tipped over", sender="a_wt", severity="warning"
)


class _Hosting:
    fleet: Any = None


def test_a_notice_is_said_with_its_sender_and_kept(tmp_path: Path) -> None:
    said: list[str] = []
    scenario = Scenario(name="t", steps=(Step(say="pour"),))
    runner = ScenarioRunner(scenario, tmp_path, hosting=_Hosting(), echo=said.append)  # type: ignore[arg-type]
    record = CommandRecord(1, "pour", "p-1")
    runner.commands.append(record)
    runner._take("report", NOTICE)
    runner._take("report", HumanReport(request_id="p-1", kind=ReportKind.ACCEPTED, text="I will pour."))
    assert [line.split("] ", 1)[1] for line in said] == [
        "a_hi → person: notice from a_wt (warning): the jar tipped over",
        "a_hi → person (#1): accepted: I will pour.",
    ]
    assert [n for _, n in runner.notices] == [NOTICE]
    assert [r.kind for r in record.reports] == [ReportKind.ACCEPTED]  # the command's reports only
    outcome = ScenarioOutcome(runner.commands, notices=runner.notices)
    assert outcome.summary().splitlines()[-1].endswith("notice from a_wt (warning): the jar tipped over")


def test_the_summary_lists_the_last_notices_and_counts_the_earlier_ones() -> None:
    many = [(float(i), NOTICE) for i in range(SUMMARY_NOTICES + 3)]
    lines = ScenarioOutcome([], notices=many).summary().splitlines()
    assert lines[0] == "(3 earlier notices to the person: see the run's report)"
    assert len(lines) == SUMMARY_NOTICES + 1 and lines[1].startswith("[    3.0 s] notice from a_wt")
