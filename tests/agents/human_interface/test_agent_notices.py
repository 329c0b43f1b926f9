"""a_hi passes on what any agent tells the person (protocol ``roco-notify``, L_HC ``Notice``, or
any notice protocol with any term the codec knows) on a channel the specification adds — C9
from a watcher, a_wt (tests/support/notice_agents.py) — with no edit of a_hi: a ``notice``
report naming the sender and what the term says (shared/fipa_codec/languages/told.py); a
protocol of two messages is no notice protocol; a malformed notice is answered
``not-understood`` and a_hi goes on; a flood is bounded per sender (notices.py)."""

from __future__ import annotations

import itertools
import logging
import queue
from collections.abc import Iterator

import msgspec
import pytest

from services.agents.human_interface.agent import HumanInterface
from services.runtime import keys
from services.runtime.human import NOTICES_PER_S, HumanReport, ReportKind
from services.runtime.roles import EVERY_NOTICE, RoleMismatch, agent_problems, participant
from services.spec.model import SystemSpec
from shared.fipa_codec import Performative, decode
from shared.fipa_codec.languages import extend
from shared.fipa_codec.languages.l_hc import MAX_NOTICE_CHARS, CommandOutcome, Notice, Severity
from shared.fipa_codec.languages.told import CUT
from tests.agents.human_interface.test_agent import TIMEOUT, Stage
from tests.support.codec_registry import languages_restored
from tests.support.notice_agents import (
    ANY_TERM_SPEC,
    CHANNEL,
    CHAT,
    CHAT_SPEC,
    SPEC,
    TERMS,
    WARNING,
    WARNING_SPEC,
    WATCHER,
    Broken,
    Fallen,
    Long,
    Plain,
)
from tests.support.notice_watcher import WarningWatcher, Watcher

TIPPED = Notice(text="the jar tipped over", severity=Severity.WARNING, about=("jar",))


@pytest.fixture
def watcher_terms() -> Iterator[None]:
    """The watcher's own terms in L_HC, as its ``terms`` module would put them there
    (services/spec/terms.py), for the test only."""
    with languages_restored():
        extend("L_HC", *TERMS)
        yield


def _start(
    stage: Stage, spec: SystemSpec = SPEC, watcher_class: type[Watcher] = Watcher
) -> tuple[HumanInterface, Watcher]:
    hi = HumanInterface(stage.bus.transport(), spec)
    stage.hi = hi
    stage.start(hi)
    watcher = watcher_class(stage.bus.transport(), spec)
    stage.start(watcher)
    return hi, watcher


def _notices(stage: Stage, n: int) -> list[HumanReport]:
    """The next ``n`` notices the person gets (a notice answers no request: request id "")."""
    return [stage.person.next("", timeout=TIMEOUT) for _ in range(n)]


def _answers_to_watcher(stage: Stage) -> queue.SimpleQueue[Performative]:
    """The performative of every communicate a_hi sends a_wt on C9, as it is sent."""
    got: queue.SimpleQueue[Performative] = queue.SimpleQueue()
    stage.bus.subscribe(keys.fipa_key(CHANNEL, "a_hi", WATCHER), lambda k, p: got.put(decode(p).performative))
    return got


@pytest.mark.walkthrough
def test_a_new_agent_on_a_channel_of_its_own_tells_the_person_with_its_name(stage: Stage) -> None:
    hi, watcher = _start(stage)
    assert (
        hi.roles.role(CHANNEL, "roco-notify").role == "participant"
    )  # no edit of a_hi: its role on every channel
    watcher.tell(TIPPED)
    (report,) = _notices(stage, 1)
    assert report == HumanReport(
        request_id="",
        kind=ReportKind.NOTICE,
        text="the jar tipped over",
        sender=WATCHER,
        severity="warning",
        about=("jar",),
    )
    assert report.notice_line == "notice from a_wt (warning, about jar): the jar tipped over"
    assert hi.counters["notices"] == 1


def test_an_a_hi_that_named_its_channels_one_by_one_refuses_the_new_one() -> None:
    """The role on every channel is what serves C9: an a_hi with the role on C8 alone refuses
    to start on the specification with C9."""
    roles = tuple(r for r in HumanInterface.ROLES if r.protocol != EVERY_NOTICE)

    class NamedChannels(HumanInterface):
        ROLES = (*roles, participant("C8", "roco-notify", "L_HC"))

    problems = agent_problems(SPEC, "a_hi", NamedChannels)
    assert any("declares no participant role for roco-notify on C9" in p for p in problems), problems
    with pytest.raises(RoleMismatch):
        NamedChannels(Stage().bus.transport(), SPEC)


@pytest.mark.walkthrough
def test_a_notice_protocol_of_its_own_with_a_term_of_its_own_is_told_by_the_term(
    stage: Stage, watcher_terms: None
) -> None:
    """``kitchen-warning``, declared in the table with one inform that nothing answers, is a
    notice protocol by its state machine: a_hi, as it is, is its participant on C9, and tells
    the person the term's own sentence (``told()``), or a term's string form when it has none."""
    hi, watcher = _start(stage, WARNING_SPEC, WarningWatcher)
    assert hi.roles.role(CHANNEL, WARNING).role == "participant"
    watcher.tell(Fallen(object="bowl", tilt_deg=170.0), Plain(name="cup"))
    tipped, plain = _notices(stage, 2)
    assert tipped == HumanReport(
        request_id="", kind=ReportKind.NOTICE, text="the bowl has tipped over", sender=WATCHER
    )
    assert tipped.notice_line == "notice from a_wt: the bowl has tipped over"
    assert plain.text == "Plain(name='cup')" and plain.sender == WATCHER
    assert hi.counters["notices"] == 2


@pytest.mark.walkthrough
def test_a_term_s_over_long_sentence_is_cut_to_a_notice_s_length(stage: Stage, watcher_terms: None) -> None:
    _, watcher = _start(stage, WARNING_SPEC, WarningWatcher)
    watcher.tell(Long(n=MAX_NOTICE_CHARS + 40), Long(n=MAX_NOTICE_CHARS))
    cut, whole = _notices(stage, 2)
    assert cut.text == "a" * (MAX_NOTICE_CHARS - 1) + CUT and whole.text == "a" * MAX_NOTICE_CHARS


@pytest.mark.walkthrough
def test_a_term_whose_told_fails_is_counted_and_a_hi_goes_on(
    stage: Stage, watcher_terms: None, caplog: pytest.LogCaptureFixture
) -> None:
    hi, watcher = _start(stage, WARNING_SPEC, WarningWatcher)
    caplog.set_level(logging.WARNING, logger=hi.log.name)
    watcher.tell(Broken(n=1), Fallen(object="cup", tilt_deg=95.0))
    (report,) = _notices(stage, 1)
    assert report.text == "the cup has tipped over"
    assert hi.counters["notices_unreadable"] == 1 and hi.counters["notices"] == 1
    assert any("Broken.told() failed: no sentence for 1" in r.getMessage() for r in caplog.records)


def test_a_protocol_of_two_messages_is_no_notice_protocol() -> None:
    """``chat`` (an inform answered by an inform) on a channel to a_hi: a_hi's role on every
    notice protocol does not stand for it, so a_hi, which declares no role for it, refuses to
    start."""
    problems = agent_problems(CHAT_SPEC, "a_hi", HumanInterface)
    assert (
        f"agent a_hi declares no participant role for {CHAT} on {CHANNEL}, which [[channels]] "
        f"{CHANNEL} gives it (in L_HC)"
    ) in problems
    with pytest.raises(RoleMismatch, match=f"for {CHAT} on {CHANNEL}"):
        HumanInterface(Stage().bus.transport(), CHAT_SPEC)


@pytest.mark.walkthrough
def test_a_malformed_notice_is_answered_not_understood_and_a_hi_goes_on(stage: Stage) -> None:
    answers = _answers_to_watcher(stage)
    hi, watcher = _start(stage)
    watcher.tell(Notice(text="x" * (MAX_NOTICE_CHARS + 1)))
    assert answers.get(timeout=TIMEOUT) is Performative.NOT_UNDERSTOOD
    watcher.tell(TIPPED)
    (report,) = _notices(stage, 1)
    assert report.text == TIPPED.text and report.sender == WATCHER
    assert hi.counters["notices"] == 1 and hi.counters["rejected"] == 1


@pytest.mark.walkthrough
def test_another_l_hc_term_is_told_by_its_string_form(stage: Stage) -> None:
    """On a channel that names no ``contents``, another L_HC term passes the runtime's check:
    it has no ``told()``, so the person reads its string form."""
    hi, watcher = _start(stage, ANY_TERM_SPEC)
    outcome = CommandOutcome(command_id="c", succeeded=True)
    watcher.tell(outcome, TIPPED)
    said, report = _notices(stage, 2)
    assert said.text == str(outcome) and said.severity == "" and report.text == TIPPED.text
    assert hi.counters["notices_unreadable"] == 0 and hi.counters["notices"] == 2


@pytest.mark.walkthrough
def test_a_flood_is_bounded_per_sender_each_second(stage: Stage, caplog: pytest.LogCaptureFixture) -> None:
    """50 notices in one second of a_hi's gate: the first NOTICES_PER_S are passed on, the
    rest counted and dropped with one log line; the next second's first is passed on."""
    hi, watcher = _start(stage)
    flood = 50
    times = itertools.chain([100.0] * flood, itertools.repeat(101.5))
    hi.notices.clock = lambda: next(times)  # a_hi's gate reads it once per notice, on a_hi's thread
    caplog.set_level(logging.WARNING, logger=hi.log.name)
    watcher.tell(*(Notice(text=f"n{i}") for i in range(flood)), Notice(text="next second"))
    texts = [r.text for r in _notices(stage, NOTICES_PER_S + 1)]
    assert texts == [f"n{i}" for i in range(NOTICES_PER_S)] + ["next second"]
    assert hi.counters["notices_dropped"] == flood - NOTICES_PER_S
    assert hi.notices.dropped == flood - NOTICES_PER_S
    said = [r for r in caplog.records if "notices from a_wt" in r.getMessage()]
    assert len(said) == 1, [r.getMessage() for r in said]


def test_notice_reports_keep_the_person_s_report_format() -> None:
    """A notice decodes as the tools decode reports (services/runtime/reports.py); an old
    report without the notice fields still decodes."""
    old = b'{"request_id":"r1","kind":"succeeded","text":"done"}'
    assert msgspec.json.decode(old, type=HumanReport).sender == ""
    notice = HumanReport(request_id="", kind=ReportKind.NOTICE, text="t", sender="a_wt")
    assert msgspec.json.decode(msgspec.json.encode(notice), type=HumanReport) == notice
    assert notice.notice_line == "notice from a_wt: t"
