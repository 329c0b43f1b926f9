"""The report's "Notices to the person" section (services/report/notices.py): every L_HC
``Notice`` an agent sent a_hi (protocol roco-notify) in the record, with time, sender and text; no
section when there is none."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from services.report import build_report
from services.report.markdown import render
from services.report.model import NoticeRow
from shared.fipa_codec.languages.l_hc import Notice, Severity, StatusQuery
from tests.report.conftest import RunBuilder

TIPPED = Notice(text="the jar tipped over", severity=Severity.WARNING, about=("jar",))


def _run(*notices: tuple[float, str, Notice]) -> RunBuilder:
    b = RunBuilder()
    b.add(1.0, "C2", "a_hi", "a_co", "query-ref", StatusQuery(), conversation="s", protocol="fipa-query")
    for i, (t, sender, notice) in enumerate(notices):
        b.add(t, "C9", sender, "a_hi", "inform", notice, conversation=f"n{i}", protocol="roco-notify")
    return b


def test_each_notice_is_a_row_with_time_sender_and_text(make_run: Callable[..., Path]) -> None:
    run_dir = make_run(_run((3.5, "a_wt", TIPPED), (7.5, "a_wt", Notice(text="the cup is back"))))
    report = build_report(run_dir)
    assert report.notices == [
        NoticeRow(t=3.5, sender="a_wt", severity="warning", text="the jar tipped over", about=["jar"]),
        NoticeRow(t=7.5, sender="a_wt", severity="info", text="the cup is back"),
    ]
    text = render(report)
    section = text[text.index("Notices to the person") :]
    assert "| 3.5 | a_wt | warning | jar | the jar tipped over |" in section
    assert "| 7.5 | a_wt | info | — | the cup is back |" in section


def test_no_notice_no_section(make_run: Callable[..., Path]) -> None:
    run_dir = make_run(_run())
    assert build_report(run_dir).notices == []
    assert "Notices to the person" not in render(build_report(run_dir))
