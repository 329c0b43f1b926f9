"""The report's "Notices to the person" section (services/report/notices.py): every inform of a
notice protocol (roco-notify in the shipped specification) or carrying an L_HC ``Notice`` in
the record, with time, sender and what it tells the person (a Notice's text, a term's own
``told()``, else its string form); an inform of another protocol is none; no section when
there is none."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from services.report import build_report
from services.report.markdown import render
from services.report.model import NoticeRow
from shared.fipa_codec.languages import extend
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    Notice,
    Progress,
    Severity,
    StatusQuery,
    TaskState,
)
from tests.report.conftest import RunBuilder
from tests.support.codec_registry import languages_restored
from tests.support.notice_agents import Fallen, Plain

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


@pytest.fixture
def watcher_terms() -> Iterator[None]:
    """A watcher's own terms in L_HC, for the test only (services/spec/terms.py puts them there
    for a specification whose agent names them)."""
    with languages_restored():
        extend("L_HC", Fallen, Plain)
        yield


def test_a_term_of_a_notice_protocol_is_told_by_its_own_sentence_or_string_form(
    make_run: Callable[..., Path], watcher_terms: None
) -> None:
    """Informs of roco-notify (a notice protocol by its state machine) carrying terms other
    than a Notice are rows with what a_hi told the person; an inform of fipa-subscribe (a
    stream, no notice protocol) to a_hi is none."""
    b = _run()
    b.add(
        2.0,
        "C9",
        "a_wt",
        "a_hi",
        "inform",
        Fallen(object="bowl", tilt_deg=170.0),
        conversation="w1",
        protocol="roco-notify",
    )
    b.add(3.0, "C9", "a_wt", "a_hi", "inform", Plain(name="cup"), conversation="w2", protocol="roco-notify")
    outcome = CommandOutcome(command_id="c", succeeded=True)
    b.add(4.0, "C9", "a_wt", "a_hi", "inform", outcome, conversation="w3", protocol="roco-notify")
    b.add(
        5.0,
        "C2",
        "a_co",
        "a_hi",
        "inform",
        Progress(command_id="c", state=TaskState.RUNNING),
        conversation="p",
        protocol="fipa-subscribe",
    )
    report = build_report(make_run(b))
    assert report.notices == [
        NoticeRow(t=2.0, sender="a_wt", severity="", text="the bowl has tipped over"),
        NoticeRow(t=3.0, sender="a_wt", severity="", text="Plain(name='cup')"),
        NoticeRow(t=4.0, sender="a_wt", severity="", text=str(outcome)),
    ]
    assert "| 2.0 | a_wt | — | — | the bowl has tipped over |" in render(report)
