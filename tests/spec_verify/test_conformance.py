"""``roco spec verify RUN``: the recorded traffic of a run conforms to the specification
(paper §4 steps 3–4; FIPA SC00026/27/35 and the coordinate protocol, §5.4).

A pour by the six agents on a MemoryBus conforms in full; traffic broken on purpose shows
each violation, with its communicate, conversation and the state machine's own words."""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path

import pytest

from services.recorder.record import TRAFFIC_RAW
from services.recorder.recorder import TrafficWriter
from services.runtime import keys
from services.runtime.transport import Arrival
from services.spec.model import default_spec
from services.spec_check.conformance import ConformanceReport, render, verify_report, verify_run
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    ProgressSubscription,
    Sentence,
    SentenceReport,
    TaskAtom,
    TaskState,
)
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery
from tests.support.memory_fleet import MemoryFleet
from tests.support.messages import communicate

P = Performative


def write_run(run_dir: Path, published: list[tuple[str, bytes]]) -> Path:
    """Record ``published`` (key, payload) pairs as the traffic recorder would, 10 ms apart."""
    writer = TrafficWriter(run_dir)
    for i, (key, payload) in enumerate(published):
        if key.startswith("roco/fipa/"):
            writer.write(1000.0 + 0.01 * i, key, payload)
    writer.close()
    return run_dir


@pytest.fixture(scope="module")
def pour_traffic() -> list[tuple[str, bytes]]:
    """What the agents of a pour published, (key, payload) in order."""
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("pour the jar into the bowl")
        assert reports[-1].kind.value == "succeeded"
        published = list(fleet.bus.published)
        violations = {a.name: a.counters["protocol_violations"] for a in fleet.agents}
    assert set(violations.values()) == {0}  # and the runtime refused nothing either
    return published


@pytest.fixture(scope="module")
def pour_run(tmp_path_factory: pytest.TempPathFactory, pour_traffic: list[tuple[str, bytes]]) -> Path:
    return write_run(tmp_path_factory.mktemp("pour"), pour_traffic)


def test_a_retransmitted_inform_and_the_confirm_sent_again_are_copies_not_steps(
    pour_traffic: list[tuple[str, bytes]], tmp_path: Path
) -> None:
    """A partition mid-pour: a_ta's L_SW inform is retransmitted byte for byte, and a_co, which
    had it, publishes its confirm again. The record holds both twice; the verifier, the report
    and ``roco sniff`` take each second one as a copy (once counted as a second inform in state
    ``reported``, a violation)."""
    from services.report import build_report
    from services.report.load import load_run
    from services.sniff.sniffer import _clock, _one, parse_filters

    c1 = keys.fipa_key("C1", "a_ta", "a_co"), keys.fipa_key("C1", "a_co", "a_ta")
    at = next(i for i, (k, p) in enumerate(pour_traffic) if k == c1[0] and b"sw" in p)
    confirm = next(i for i in range(at, len(pour_traffic)) if pour_traffic[i][0] == c1[1])
    later = next(i for i in range(confirm, len(pour_traffic)) if pour_traffic[i][0] == c1[0])
    copies = [pour_traffic[at], pour_traffic[confirm]]  # after a_ta's next inform, as 5 s later
    report = verify(tmp_path, *pour_traffic[: later + 1], *copies, *pour_traffic[later + 1 :])
    assert report.full_conformance and report.copies == 2, render(report)
    assert "copies: 2 communicate(s) recorded again byte for byte" in render(report)
    marked = [m for m in load_run(tmp_path).messages if m.copy_of is not None]
    assert [m.rec.key for m in marked] == [c1[0], c1[1]]
    assert any("2 communicate(s) recorded again" in n for n in build_report(tmp_path).notes)
    # roco sniff shows a copy as one line naming the first arrival, and does not count it
    earlier: OrderedDict[bytes, float] = OrderedDict()
    filters = parse_filters(agents=None, channels=None, performatives=None, conversation=None)
    key, payload = pour_traffic[at]
    first = _one(filters, 1000.0, key, payload, True, earlier)
    again = _one(filters, 1005.0, key, payload, True, earlier)
    assert first is not None and first[1] is True
    assert again is not None and again[1] is False
    assert again[0].endswith(f"copy of the communicate at {_clock(1000.0)}") and "\n" not in again[0]


def test_the_traffic_of_a_pour_conforms_in_full(pour_run: Path) -> None:
    report = verify_run(pour_run, default_spec())
    assert report.full_conformance, render(report)
    assert report.violations == [] and report.unchecked == 0 and report.not_understood == []
    assert set(report.per_protocol) == {"fipa-request", "fipa-query", "fipa-subscribe", "coordinate"}
    assert report.conforming == len(report.conversations)
    assert report.communicates == sum(c.messages for c in report.conversations)
    # only the agreed subscriptions are left open: they last while the system runs
    still = report.open_conversations
    assert still and all(c.open_by_design and not c.unanswered for c in still)
    # a_km's environment subscription: its latest attempt (km-environment, or -2, -3 … when it asked again)
    assert any(c.conversation_id.partition("-environment")[0] == "km" for c in still), still
    ok, text = verify_report(pour_run, None)
    assert ok and text.endswith("full conformance: yes")
    assert "(an agreed subscription lasts while the system runs)" in text and "violations: none" in text


# ---- traffic broken on purpose -----------------------------------------------------------------


comm = communicate


def on(channel: str, msg: Communicate) -> tuple[str, bytes]:
    assert msg.sender is not None
    return keys.fipa_key(channel, msg.sender.name, msg.receiver[0].name), encode(msg)


COMMAND = HumanCommand(text="pour the jar into the bowl", goal=TaskAtom("pour", ("jar", "bowl")))
OUTCOME = CommandOutcome(command_id="cmd-1", succeeded=True)
PROGRESS = Progress(command_id="c", state=TaskState.RUNNING)


def verify(tmp_path: Path, *published: tuple[str, bytes]) -> ConformanceReport:
    return verify_run(write_run(tmp_path, list(published)), default_spec())


def found(report: ConformanceReport) -> list[tuple[int, str, str | None, int | None]]:
    return [(v.seq, v.kind, v.conversation, v.position) for v in report.violations]


def test_a_conforming_request_with_its_crossings(tmp_path: Path) -> None:
    report = verify(
        tmp_path,
        on("C2", comm(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", COMMAND)),
        on("C2", comm(P.AGREE, "a_co", "a_hi", "fipa-request", "cmd-1")),
        on("C2", comm(P.INFORM, "a_co", "a_hi", "fipa-request", "cmd-1", OUTCOME)),
        # the person's stop crossed the outcome; a_co answers it: nothing left to cancel
        on("C2", comm(P.CANCEL, "a_hi", "a_co", "fipa-request", "cmd-1", COMMAND)),
        on(
            "C2",
            comm(P.FAILURE, "a_co", "a_hi", "fipa-request", "cmd-1", content=b"no such", encoding="utf-8"),
        ),
    )
    assert report.full_conformance, render(report)
    (conversation,) = report.conversations
    assert conversation.agents == ("a_hi", "a_co") and conversation.crossings == 2
    assert conversation.ended and conversation.state == "done"


def test_a_foreign_agents_request_on_c8_conforms_as_the_external_roles(tmp_path: Path) -> None:
    """traffic that crossed roco gateway, under the JADE agent's own name, is checked
    as x_fipa's; the same request to a_co is on no channel."""
    jade = "da0@host:1099/JADE"
    said = Sentence(text="bring me the cup")
    report = verify(
        tmp_path,
        on("C8", comm(P.REQUEST, jade, "a_hi", "fipa-request", "C1_jade", said)),
        on(
            "C8",
            comm(
                P.AGREE, "a_hi", jade, "fipa-request", "C1_jade", SentenceReport(kind="accepted", text="ok")
            ),
        ),
        on(
            "C8",
            comm(
                P.INFORM, "a_hi", jade, "fipa-request", "C1_jade", SentenceReport(kind="succeeded", text="ok")
            ),
        ),
    )
    assert report.full_conformance, render(report)
    (conversation,) = report.conversations
    assert conversation.agents == (jade, "a_hi") and conversation.ended
    bad = verify(tmp_path / "bad", on("C8", comm(P.REQUEST, jade, "a_co", "fipa-request", "C2_jade", said)))
    assert found(bad) == [(0, "channel", "C2_jade", 0)]


def test_a_communicate_on_a_channel_that_does_not_join_its_agents(tmp_path: Path) -> None:
    query = comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q1", ObjectQuery("jar"))
    report = verify(
        tmp_path,
        (keys.fipa_key("C6", "a_pl", "a_km"), encode(query)),  # a_pl and a_km share C4
        on("C2", comm(P.REQUEST, "a_hi", "a_pl", "fipa-request", "r1", COMMAND)),  # no channel at all
    )
    assert found(report) == [(0, "channel", "q1", 0), (1, "channel", "r1", 0)]
    assert report.violations[0].text == "a_pl and a_km are joined by C4, not C6"
    assert report.violations[1].text == "no channel of the specification joins a_hi and a_pl"
    assert not report.full_conformance


def test_performatives_outside_the_protocol_state(tmp_path: Path) -> None:
    report = verify(
        tmp_path,
        # an inform before any request
        on("C2", comm(P.INFORM, "a_co", "a_hi", "fipa-request", "cmd-1", OUTCOME)),
        # an inform before the subscription is agreed
        on("C2", comm(P.SUBSCRIBE, "a_hi", "a_co", "fipa-subscribe", "sub", ProgressSubscription())),
        on("C2", comm(P.INFORM, "a_co", "a_hi", "fipa-subscribe", "sub", PROGRESS)),
        # coordinate: a confirm before a_ta reported anything
        on("C1", comm(P.REQUEST, "a_co", "a_ta", "coordinate", "exec", content=b"", language=None)),
        on("C1", comm(P.CONFIRM, "a_co", "a_ta", "coordinate", "exec", SWStatus(state=SWState.RUNNING))),
    )
    assert found(report) == [
        (0, "protocol-state", "cmd-1", 0),
        (2, "protocol-state", "sub", 1),
        (4, "protocol-state", "exec", 1),
    ]
    texts = [v.text for v in report.violations]
    assert texts[0] == (
        "fipa-request: the participant may not send 'inform' in state 'start'; allowed: initiator request"
    )
    assert texts[1].startswith("fipa-subscribe: the participant may not send 'inform' in state 'subscribed'")
    assert texts[2].startswith("coordinate: the initiator may not send 'confirm' in state 'requested'")
    by_id = {c.conversation_id: c for c in report.conversations}
    assert by_id["sub"].violations == 1 and by_id["exec"].violations == 1
    assert report.conforming == 0


def test_content_in_the_wrong_language_or_ontology_or_not_decoding(tmp_path: Path) -> None:
    status = SWStatus(state=SWState.IDLE)
    lang, body = encode_content(ObjectQuery("jar"))
    report = verify(
        tmp_path,
        on("C4", comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q1", status)),  # L_SW on C4
        on("C4", comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q2", ObjectQuery("jar"), ontology=None)),
        on(
            "C4",
            comm(
                P.QUERY_REF,
                "a_pl",
                "a_km",
                "fipa-query",
                "q3",
                content=b"\x91\x01",
                language=lang,
                ontology="O_RoCo",
            ),
        ),
        on("C4", comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q4", content=body, language=None)),
        on("C4", comm(P.INFORM_REF, "a_km", "a_pl", "fipa-query", "q2", Answer())),  # fine
    )
    assert found(report) == [
        (0, "language", "q1", 0),
        (1, "ontology", "q2", 0),
        (2, "content", "q3", 0),
        (3, "language", "q4", 0),
    ]
    texts = [v.text for v in report.violations]
    assert texts[0] == "query-ref in fipa-query on C4 must be in L_WM, not L_SW"
    assert texts[1] == "language L_WM needs ontology O_RoCo, not None"
    assert texts[2].startswith("L_WM: ")
    assert texts[3] == "query-ref carries content but names no language"


def test_the_wrong_role_a_wrong_key_and_a_payload_that_is_no_communicate(tmp_path: Path) -> None:
    query = comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q1", ObjectQuery("jar"))
    report = verify(
        tmp_path,
        on("C4", comm(P.QUERY_REF, "a_km", "a_pl", "fipa-query", "q0", ObjectQuery("jar"))),
        (keys.fipa_key("C4", "a_ta", "a_km"), encode(query)),
        (keys.fipa_key("C4", "a_pl", "a_km"), b"\x93not a communicate"),
    )
    assert found(report) == [(0, "performative", "q0", 0), (1, "key", "q1", 0), (2, "malformed", None, None)]
    assert report.violations[0].text == (
        "the participant of fipa-query on C4 (a_km) may not send query-ref "
        "(allowed: refuse, agree, failure, inform, inform-ref, not-understood)"
    )
    assert report.violations[1].text == "the key names sender a_ta, the communicate a_pl"


def test_a_not_understood_ends_the_conversation_and_is_listed(tmp_path: Path) -> None:
    report = verify(
        tmp_path,
        on("C4", comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q1", ObjectQuery("jar"))),
        on(
            "C4", comm(P.NOT_UNDERSTOOD, "a_km", "a_pl", "fipa-query", "q1", content=b"why", encoding="utf-8")
        ),
        on("C4", comm(P.INFORM_REF, "a_km", "a_pl", "fipa-query", "q1", Answer())),  # after its own end
    )
    (nu,) = report.not_understood
    assert (nu.seq, nu.sender, nu.text) == (1, "a_km", "why")
    assert report.conversations[0].not_understood and report.open_conversations == []
    # nothing belongs to the conversation after the not-understood that ended it, whoever sends it
    (late,) = report.violations
    assert (late.seq, late.kind) == (2, "protocol-state") and "already ended" in late.text


def test_the_rendered_report_names_each_violation(tmp_path: Path) -> None:
    report = verify(
        tmp_path,
        on("C2", comm(P.SUBSCRIBE, "a_hi", "a_co", "fipa-subscribe", "sub", ProgressSubscription())),
        on("C2", comm(P.INFORM, "a_co", "a_hi", "fipa-subscribe", "sub", PROGRESS)),
    )
    text = render(report)
    assert (
        "seq 1 t=0.010 s C2 a_co→a_hi inform fipa-subscribe (conversation sub #1) [protocol-state] "
        "fipa-subscribe: the participant may not send 'inform' in state 'subscribed'"
    ) in text
    assert "open at the end of the record: 1" in text
    assert text.endswith("full conformance: no (1 violation(s))")


def subscribe(cid: str, reply_by: float | None) -> tuple[str, bytes]:
    """a_hi's progress subscription ``cid`` (reply-with ``cid``), to be answered by ``reply_by``
    (POSIX s; the records written by :func:`write_run` begin at 1000.0 s, 10 ms apart)."""
    return on(
        "C2",
        comm(
            P.SUBSCRIBE,
            "a_hi",
            "a_co",
            "fipa-subscribe",
            cid,
            ProgressSubscription(),
            reply_with=cid,
            reply_by=reply_by,
        ),
    )


def answer(performative: Performative, cid: str, term: Progress | None = None) -> tuple[str, bytes]:
    return on("C2", comm(performative, "a_co", "a_hi", "fipa-subscribe", cid, term, in_reply_to=cid))


def test_a_subscribe_never_agreed_nor_refused_is_a_violation(tmp_path: Path) -> None:
    """FIPA SC00035 §2: the participant answers a subscribe with agree or refuse. One whose
    reply-by passed with no answer (a_co let a_hi's first attempt time out, a_hi subscribed
    again) is a violation; one without a reply-by, never answered, too. An agreed subscription
    is listed open, as it lasts while the system runs; a refused one has ended."""
    report = verify(
        tmp_path,
        subscribe("hi-progress", reply_by=1000.0),  # seq 0: never answered, reply-by passed
        on("C2", comm(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", COMMAND)),
        on("C2", comm(P.AGREE, "a_co", "a_hi", "fipa-request", "cmd-1")),
        subscribe("hi-progress-2", reply_by=1005.0),  # seq 3: agreed, informed
        answer(P.AGREE, "hi-progress-2"),
        answer(P.INFORM, "hi-progress-2", Progress(command_id="cmd-1", state=TaskState.PLANNING)),
        subscribe("hi-progress-3", reply_by=None),  # seq 6: never answered, no reply-by at all
        subscribe("hi-progress-4", reply_by=1005.0),  # seq 7: refused
        on(
            "C2",
            comm(
                P.REFUSE, "a_co", "a_hi", "fipa-subscribe", "hi-progress-4", content=b"no", encoding="utf-8"
            ),
        ),
    )
    assert found(report) == [(0, "unanswered", "hi-progress", 0), (6, "unanswered", "hi-progress-3", 0)]
    first, third = report.violations
    assert (first.sender, first.receiver, first.performative, first.channel) == (
        "a_hi",
        "a_co",
        "subscribe",
        "C2",
    )
    # the record ends at 1000.08 s
    assert first.text == (
        "a_co never agreed to nor refused the subscribe (its reply-by passed 0.1 s before the record ended)"
    )
    assert third.text == "a_co never agreed to nor refused the subscribe (it names no reply-by)"
    assert not report.full_conformance
    by_id = {c.conversation_id: c for c in report.conversations}
    assert by_id["hi-progress"].unanswered and by_id["hi-progress"].violations == 1
    assert by_id["hi-progress-2"].open_by_design and not by_id["hi-progress-2"].unanswered
    assert by_id["hi-progress-4"].ended and not by_id["hi-progress-4"].unanswered
    assert report.conforming == len(report.conversations) - 2
    text = render(report)
    assert "hi-progress a_hi→a_co fipa-subscribe in state subscribed" in text
    assert text.count("(never agreed nor refused: a violation)") == 2
    assert text.count("(an agreed subscription lasts while the system runs)") == 1
    assert "open by design" not in text
    assert text.endswith("full conformance: no (2 violation(s))")


def test_a_subscribe_still_within_its_reply_by_when_the_record_ends_is_only_open(tmp_path: Path) -> None:
    """A run cut short just after a subscribe: its answer may still come, so it is listed open."""
    report = verify(tmp_path, subscribe("hi-progress", reply_by=1005.0))
    assert report.full_conformance, render(report)
    (still,) = report.open_conversations
    assert not still.unanswered and not still.open_by_design and still.state == "subscribed"


def test_a_late_agree_of_an_attempt_given_up_and_its_cancel_conform(tmp_path: Path) -> None:
    """a_co answered a_hi's first attempt after its reply-by, with the progress it kept; a_hi,
    already on its second attempt, cancels the first (cancel meta-protocol): nothing is
    unanswered."""
    progress = Progress(command_id="cmd-1", state=TaskState.WAITING, detail="accepted")
    report = verify(
        tmp_path,
        subscribe("hi-progress", reply_by=1000.0),
        subscribe("hi-progress-2", reply_by=1005.0),
        answer(P.AGREE, "hi-progress"),
        answer(P.INFORM, "hi-progress", progress),
        answer(P.AGREE, "hi-progress-2"),
        on("C2", comm(P.CANCEL, "a_hi", "a_co", "fipa-subscribe", "hi-progress", ProgressSubscription())),
        on("C2", comm(P.INFORM, "a_co", "a_hi", "fipa-subscribe", "hi-progress", None)),
    )
    assert report.full_conformance, render(report)
    by_id = {c.conversation_id: c for c in report.conversations}
    assert by_id["hi-progress"].ended and by_id["hi-progress-2"].open_by_design


def test_missing_payloads_an_empty_record_and_no_folder_are_not_full_conformance(tmp_path: Path) -> None:
    run = write_run(
        tmp_path / "run", [on("C4", comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q", ObjectQuery("j")))]
    )
    (run / TRAFFIC_RAW).unlink()
    report = verify_run(run, default_spec())
    assert report.unchecked == 1 and report.violations == [] and not report.full_conformance
    (tmp_path / "empty").mkdir()
    ok, text = verify_report(tmp_path / "empty", None)
    assert not ok and text.endswith("full conformance: no (no communicates recorded)")
    ok, text = verify_report(tmp_path / "nowhere", None)
    assert (ok, text) == (False, f"{tmp_path / 'nowhere'}: no such run folder")
    ok, text = verify_report(run, tmp_path / "missing.toml")
    assert not ok and "no such specification file" in text


def test_a_term_the_specification_does_not_list_for_the_performative_is_a_violation(tmp_path: Path) -> None:
    report = verify(
        tmp_path,
        on("C2", comm(P.SUBSCRIBE, "a_hi", "a_co", "fipa-subscribe", "sub", ProgressSubscription())),
        on("C2", comm(P.AGREE, "a_co", "a_hi", "fipa-subscribe", "sub", None)),
        on("C2", comm(P.INFORM, "a_co", "a_hi", "fipa-subscribe", "sub", OUTCOME)),
    )
    [v] = report.violations
    assert v.kind == "content"
    assert (
        v.text == "inform in fipa-subscribe on C2 carries a CommandOutcome; the specification allows Progress"
    )


def test_an_answer_recorded_before_its_query_is_checked_after_it(tmp_path: Path) -> None:
    """The recorder sees different publishers in no fixed order (seen in CI: a_km's
    inform-ref recorded before a_pl's query-ref). An answer whose in-reply-to names a later
    reply-with of its conversation is checked after it; one that names nothing recorded is not
    moved and stays a violation."""
    query = comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q1", ObjectQuery("jar"), reply_with="r1")
    answer = comm(P.INFORM_REF, "a_km", "a_pl", "fipa-query", "q1", Answer(), in_reply_to="r1")
    report = verify(tmp_path / "swapped", on("C4", answer), on("C4", query))
    assert report.full_conformance, render(report)
    assert report.conversations[0].ended
    assert any("checked in causal order" in n for n in report.notes)
    stray = comm(P.INFORM_REF, "a_km", "a_pl", "fipa-query", "q2", Answer(), in_reply_to="nothing")
    query2 = comm(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q2", ObjectQuery("jar"), reply_with="r2")
    report = verify(tmp_path / "stray", on("C4", stray), on("C4", query2))
    assert found(report) == [(0, "protocol-state", "q2", 0)]
    assert not any("causal order" in n for n in report.notes)


def test_across_a_cut_link_the_copies_are_judged_once_whichever_order_the_recorder_got_them_in(
    pour_traffic: list[tuple[str, bytes]], tmp_path: Path
) -> None:
    """Issue 45, as the brain's recorder saw it: a_ta's L_SW inform was put while the link was
    cut and retransmitted 5 s later under the next sequence number of its publisher; a_co
    confirmed it, and sent the confirm again for the copy. Over the two hosts' paths a_co's
    confirm reached the recorder before the inform it answers, and the confirm's copy before
    the inform's copy. Each copy is judged once, as its original, in causal order."""
    from services.report import build_report

    c1 = keys.fipa_key("C1", "a_ta", "a_co"), keys.fipa_key("C1", "a_co", "a_ta")
    at = next(i for i, (k, p) in enumerate(pour_traffic) if k == c1[0] and b"sw" in p)
    confirm = next(i for i in range(at, len(pour_traffic)) if pour_traffic[i][0] == c1[1])
    inform, confirmed = pour_traffic[at], pour_traffic[confirm]
    rest = [kp for i, kp in enumerate(pour_traffic) if i not in (at, confirm)]
    before, after = rest[:at], rest[at:]
    # arrival order at the recorder: …, confirm, inform, confirm's copy, inform's copy, …
    run = record_from_publishers(tmp_path / "cut", [*before, confirmed, inform, confirmed, inform, *after])
    report = verify_run(run, default_spec())
    assert report.record.intact and report.copies == 2, render(report)
    assert report.full_conformance, render(report)
    (plan,) = [c for c in report.conversations if c.conversation_id == decode(inform[1]).conversation_id]
    assert plan.protocol == "coordinate" and plan.violations == 0 and plan.ended
    # the report tells the run as it tells the same run without the copies
    built = build_report(run)
    alone = build_report(record_from_publishers(tmp_path / "alone", [*before, confirmed, inform, *after]))
    assert any("2 communicate(s) recorded again" in n for n in built.notes)
    assert [(e.kind, e.text) for e in built.events] == [(e.kind, e.text) for e in alone.events]


def test_an_inform_recorded_before_the_confirm_it_waited_for_is_checked_after_it(
    pour_traffic: list[tuple[str, bytes]], tmp_path: Path
) -> None:
    """Seen in a test run: a_ta sent its next L_SW inform once a_co's confirm of the previous
    one had arrived, and the recorder got the inform 10 µs before that confirm. Nothing in the
    inform names the confirm: the send times order them. Sent the other way round (a_ta did
    not wait), the same arrival order stays a violation."""
    c1 = keys.fipa_key("C1", "a_ta", "a_co"), keys.fipa_key("C1", "a_co", "a_ta")
    at = next(i for i, (k, p) in enumerate(pour_traffic) if k == c1[0] and b"sw" in p)
    confirm = next(i for i in range(at, len(pour_traffic)) if pour_traffic[i][0] == c1[1])
    following = next(i for i in range(confirm, len(pour_traffic)) if pour_traffic[i][0] == c1[0])
    rest = [kp for i, kp in enumerate(pour_traffic) if i not in (confirm, following)]
    order = [*rest[: following - 1], pour_traffic[following], pour_traffic[confirm], *rest[following - 1 :]]
    inform_at = following - 1  # where they arrive: the inform, then the confirm
    for sent_first, conforms in (("confirm", True), ("inform", False)):
        early = inform_at + (1 if sent_first == "confirm" else 0)
        sent = {early: 1000.0 + 0.01 * inform_at - 0.008}  # 3 ms before the other was sent
        report = verify_run(record_from_publishers(tmp_path / sent_first, order, sent), default_spec())
        assert report.full_conformance is conforms, render(report)
        assert any("in the order they were sent" in n for n in report.notes) is conforms


def record_from_publishers(
    run_dir: Path, order: list[tuple[str, bytes]], sent: dict[int, float] | None = None
) -> Path:
    """Record the communicates of ``order`` (key, payload) as arriving in that order, 10 ms
    apart, each sent 5 ms before it arrived (``sent``: the send times of some, by position in
    ``order``) by the advanced publisher of its key (one per key: source ``zid:<key>``,
    sequence numbers 0, 1, … in order; a copy is the next number)."""
    sns: dict[str, int] = {}
    arrivals: list[Arrival] = []
    for i, (key, payload) in enumerate(order):
        if key.startswith("roco/fipa/"):
            sn = sns[key] = sns.get(key, -1) + 1
            t = 1000.0 + 0.01 * i
            arrivals.append(Arrival(t, key, payload, f"zid:{key}", sn, (sent or {}).get(i, t - 0.005)))
    run_dir.mkdir()
    writer = TrafficWriter(run_dir)
    writer.write_many(arrivals)
    writer.close()
    return run_dir
