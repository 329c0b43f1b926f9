"""What a_hi keeps of the outcomes it told (services/agents/human_interface/told.py): the final
reports of commands, bounded in number and text; not progress, not status."""

from __future__ import annotations

import msgspec

from services.agents.human_interface.told import MAX_TOLD, MAX_TOLD_TEXT, Told
from services.runtime.human import HumanReport, ReportKind
from services.runtime.reports import MAX_OUTCOMES_BYTES


def _report(rid: str, kind: ReportKind, text: str = "pour the jar into the bowl: succeeded") -> HumanReport:
    return HumanReport(request_id=rid, kind=kind, text=text)


def test_only_the_final_reports_of_commands_are_kept() -> None:
    told = Told()
    kept = [
        told.keep(_report("a", ReportKind.ACCEPTED)),
        told.keep(_report("a", ReportKind.PROGRESS)),
        told.keep(_report("s", ReportKind.STATUS)),
        told.keep(_report("a", ReportKind.SUCCEEDED)),
        told.keep(_report("b", ReportKind.NOT_UNDERSTOOD)),
    ]
    assert kept == [False, False, False, True, True]
    assert [(r.request_id, r.kind) for r in told.reports] == [
        ("a", ReportKind.SUCCEEDED),
        ("b", ReportKind.NOT_UNDERSTOOD),
    ]


def test_the_oldest_are_forgotten_and_long_texts_cut_so_the_answer_stays_bounded() -> None:
    told = Told()
    for i in range(MAX_TOLD + 5):
        told.keep(_report(f"r{i}", ReportKind.FAILED, "x" * (3 * MAX_TOLD_TEXT)))
    assert len(told.reports) == MAX_TOLD and told.reports[0].request_id == "r5"
    assert all(len(r.text) == MAX_TOLD_TEXT and r.text.endswith("…") for r in told.reports)
    answer = told.answer()
    assert len(answer) <= MAX_OUTCOMES_BYTES  # what roco send reads of it
    assert msgspec.json.decode(answer, type=list[HumanReport]) == told.reports
