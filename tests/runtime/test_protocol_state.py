"""Every communicate is checked against its conversation's protocol state when sent and when
received (at run time; FIPA SC00026/27/35, paper §5.4): refused with
not-understood, or not sent (SpecViolation), counted and logged. Crossings on the wire are
tolerated. The agents are driven by hand on a MemoryBus: no threads, no sleeps."""

from __future__ import annotations

import logging
from typing import Any

import msgspec
import pytest

from services.runtime import keys, protocol_state
from services.runtime.agent import Agent, SpecViolation
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.memory_transport import MemoryBus
from services.runtime.protocol_state import CrossingTracker, ProtocolStates, follow
from services.spec.model import default_spec
from services.spec.protocol_defs import machine_of
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery, Subscription, WorldUpdate
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, ProtocolViolation
from tests.support.messages import communicate as build

P = Performative
INIT, PART = INITIATOR, PARTICIPANT


# ---- the tracker ---------------------------------------------------------------------------


def steps(protocol: str, *messages: tuple[str, Performative], local: str | None = None) -> CrossingTracker:
    """A tracker of ``protocol``'s machine in the shipped specification (FIPA's built in, the
    paper's coordinate declared there) after ``messages``."""
    machine = machine_of(default_spec(), protocol)
    tracker = CrossingTracker(machine, local_role=INIT if local == INIT else PART if local == PART else None)
    for role, perf in messages:
        tracker.step(role, perf)
    return tracker


def test_in_order_it_is_the_protocols_state_machine() -> None:
    t = steps("fipa-request", (INIT, P.REQUEST), (PART, P.AGREE), (PART, P.INFORM))
    assert t.state == "done" and t.is_finished and t.crossings == 0
    with pytest.raises(ProtocolViolation, match="already ended in state 'done'"):
        t.step(PART, P.INFORM)
    with pytest.raises(ProtocolViolation, match="may not send 'inform' in state 'subscribed'"):
        steps("fipa-subscribe", (INIT, P.SUBSCRIBE), (PART, P.INFORM))


@pytest.mark.parametrize("first", ["coordinate", "fipa-request"])
def test_a_protocol_is_followed_alike_whatever_another_followed_first(first: str) -> None:
    """Trackers share what they computed (services/runtime/protocol_state.py ``_STEPS``), yet
    the same communicates read differently under two protocols: the participant's inform
    ends a fipa-request and reports a state in a coordinate conversation, in either order."""
    protocol_state._STEPS.clear()  # what this process followed before must not decide it
    protocol_state._READINGS.clear()
    protocol_state._INITIAL.clear()
    ended = {"fipa-request": True, "coordinate": False}
    for protocol in (first, *(p for p in ended if p != first)):
        tracker = steps(protocol, (INIT, P.REQUEST), (PART, P.INFORM))
        assert tracker.is_finished is ended[protocol], protocol


def test_an_outcome_crossing_a_cancel_and_the_late_answer_to_the_cancel() -> None:
    # the participant's view: its inform went out before the cancel arrived
    co = steps(
        "fipa-request", (INIT, P.REQUEST), (PART, P.AGREE), (PART, P.INFORM), (INIT, P.CANCEL), local=PART
    )
    assert co.crossings == 1
    co.step(PART, P.FAILURE)  # "nothing to cancel": the cancel meta-protocol's answer
    assert co.is_finished
    with pytest.raises(ProtocolViolation):
        co.step(PART, P.FAILURE)  # but only once
    # the initiator's view of the same: its cancel, then the outcome, then the late answer
    hi = steps(
        "fipa-request", (INIT, P.REQUEST), (PART, P.AGREE), (INIT, P.CANCEL), (PART, P.INFORM), local=INIT
    )
    hi.step(PART, P.FAILURE)
    assert hi.is_finished


def test_an_agents_own_communicates_keep_their_order() -> None:
    # a received communicate may still wait unread in the input buffer when the agent
    # sends, so its own may cross it; but never its own earlier ones
    t = steps("fipa-request", (INIT, P.REQUEST), (PART, P.INFORM), local=PART)
    with pytest.raises(ProtocolViolation, match="already ended in state 'done'"):
        t.step(PART, P.AGREE)
    hi = steps("fipa-request", (INIT, P.REQUEST), (PART, P.INFORM), local=INIT)
    hi.step(INIT, P.CANCEL)  # sent before it read the inform: the inform answers it
    assert hi.states == {"cancelled"}


def test_an_agree_crossing_a_cancel_and_informs_crossing_a_subscription_cancel() -> None:
    t = steps(
        "fipa-request", (INIT, P.REQUEST), (INIT, P.CANCEL), (PART, P.AGREE), (PART, P.INFORM), local=INIT
    )
    assert t.state == "cancelled" and t.may_be_finished
    s = steps(
        "fipa-subscribe",
        (INIT, P.SUBSCRIBE),
        (PART, P.AGREE),
        (INIT, P.CANCEL),
        (PART, P.INFORM),  # a change reported before the cancel arrived
        (PART, P.INFORM),  # another
        (PART, P.INFORM),  # the answer to the cancel
        local=INIT,
    )
    assert "cancelled" in s.states


def test_a_failed_cancel_leaves_the_conversation_going() -> None:
    t = steps(
        "fipa-request", (INIT, P.REQUEST), (PART, P.AGREE), (INIT, P.CANCEL), (PART, P.FAILURE), local=PART
    )
    assert not t.is_finished and t.may_be_finished
    t.step(PART, P.INFORM)  # the request was carried out after all
    assert t.is_finished


def test_a_cancel_of_a_conversation_never_seen_may_be_answered_once() -> None:
    t, outcome = follow(None, "fipa-query", INIT, P.CANCEL, local_role=PART)
    assert outcome == "forgotten" and not t.is_finished
    follow(t, "fipa-query", PART, P.FAILURE, local_role=PART)
    assert t.is_finished
    with pytest.raises(ProtocolViolation):  # an inform in a conversation never opened
        follow(None, "fipa-query", PART, P.INFORM, local_role=INIT)


def test_an_opening_communicate_in_an_open_or_ended_conversation_is_refused() -> None:
    """A conversation-id names one conversation (FIPA SC00061): a second subscribe in it, open
    or ended, is a violation, and so is anything after its end, whoever sends it."""
    t, _ = follow(None, "fipa-subscribe", INIT, P.SUBSCRIBE, local_role=INIT)
    with pytest.raises(ProtocolViolation, match="needs a new conversation-id"):
        follow(t, "fipa-subscribe", INIT, P.SUBSCRIBE, local_role=INIT)
    assert t.state == "subscribed" and t.messages == 1  # unchanged
    t, outcome = follow(t, "fipa-subscribe", PART, P.REFUSE, local_role=INIT)
    assert outcome == "step" and t.is_finished
    for role, perf in ((INIT, P.SUBSCRIBE), (PART, P.AGREE), (PART, P.INFORM)):
        with pytest.raises(ProtocolViolation, match="refused"):
            follow(t, "fipa-subscribe", role, perf, local_role=INIT)
    # a query answered, then asked again and answered again under the same id
    q, _ = follow(None, "fipa-query", INIT, P.QUERY_REF)
    follow(q, "fipa-query", PART, P.INFORM_REF)
    with pytest.raises(ProtocolViolation, match="opens a conversation"):
        follow(q, "fipa-query", INIT, P.QUERY_REF)
    # the same query three times in one open conversation: the second is refused already
    r, _ = follow(None, "fipa-query", INIT, P.QUERY_REF)
    with pytest.raises(ProtocolViolation):
        follow(r, "fipa-query", INIT, P.QUERY_REF)


def test_not_understood_comes_from_a_receiver_and_ends_the_conversation() -> None:
    """Not-understood answers a communicate received (FIPA SC00037 §3.12): the initiator of a
    query that received nothing may not send one; after the participant's agree it may, and the
    conversation ends: the inform that crossed it still belongs there, a second inform does not,
    nor anything its sender sends; a refused communicate may be answered not-understood once,
    by its receiver."""
    t, _ = follow(None, "fipa-query", INIT, P.QUERY_REF)
    with pytest.raises(ProtocolViolation, match="not-understood answers a communicate received"):
        follow(t, "fipa-query", INIT, P.NOT_UNDERSTOOD)
    assert not t.is_finished
    follow(t, "fipa-query", PART, P.AGREE)
    t, outcome = follow(t, "fipa-query", INIT, P.NOT_UNDERSTOOD)
    assert outcome == "aborted" and t.is_finished
    t, outcome = follow(t, "fipa-query", PART, P.INFORM)  # sent before the not-understood arrived
    assert outcome == "crossing"
    with pytest.raises(ProtocolViolation, match="already ended"):
        follow(t, "fipa-query", PART, P.INFORM)
    with pytest.raises(ProtocolViolation, match="not-understood answers"):  # it heard nothing since
        follow(t, "fipa-query", PART, P.NOT_UNDERSTOOD)
    # the initiator heard the refused inform: it may answer it not-understood, once
    assert follow(t, "fipa-query", INIT, P.NOT_UNDERSTOOD)[1] == "aborted"
    with pytest.raises(ProtocolViolation, match="not-understood answers"):
        follow(t, "fipa-query", INIT, P.NOT_UNDERSTOOD)
    with pytest.raises(ProtocolViolation, match="already ended"):  # nor may its sender go on
        follow(t, "fipa-query", INIT, P.CANCEL)
    # what names a not-understood in its in-reply-to was sent after it: no crossing
    u, _ = follow(None, "fipa-query", INIT, P.QUERY_REF, reply_with="q")
    follow(u, "fipa-query", PART, P.AGREE, reply_with="a", in_reply_to="q")
    follow(u, "fipa-query", INIT, P.NOT_UNDERSTOOD, reply_with="nu", in_reply_to="a")
    with pytest.raises(ProtocolViolation, match="already ended"):
        follow(u, "fipa-query", PART, P.INFORM, in_reply_to="nu")


def test_a_refused_communicate_is_noted_for_its_receiver_only() -> None:
    """``judge`` returns its refusal with the tracker, unchanged but for what its receiver
    heard; ``ProtocolStates`` keeps that for a conversation it knows and nothing for one it
    does not."""
    t, outcome, refusal = protocol_state.judge(None, "fipa-request", PART, P.INFORM, local_role=INIT)
    assert outcome is None and isinstance(refusal, ProtocolViolation) and t.initiator_heard
    table = ProtocolStates()
    with pytest.raises(ProtocolViolation):
        table.observe("a_pl", "q", "fipa-request", PART, P.INFORM, local_role=INIT)
    assert table.get("a_pl", "q") is None
    table.observe("a_pl", "r", "fipa-request", INIT, P.REQUEST, local_role=INIT)
    table.observe("a_pl", "r", "fipa-request", PART, P.INFORM, local_role=INIT)
    with pytest.raises(ProtocolViolation):
        table.observe("a_pl", "r", "fipa-request", PART, P.INFORM, local_role=INIT)
    assert table.observe("a_pl", "r", "fipa-request", INIT, P.NOT_UNDERSTOOD, local_role=INIT) == "aborted"


def test_a_long_subscription_keeps_bounded_memory() -> None:
    t = steps("fipa-subscribe", (INIT, P.SUBSCRIBE), (PART, P.AGREE))
    for _ in range(500):
        t.step(PART, P.INFORM)
    assert len(t.readings) == 1 and len(t.readings[0].run) <= t.max_run
    t.step(INIT, P.CANCEL)
    t.step(PART, P.INFORM)
    assert t.may_be_finished


def test_a_confirm_of_the_terminal_inform_closes_coordinate_at_both_ends() -> None:
    """a_co's confirm names a_ta's terminal inform in in-reply-to: it was sent after that
    inform arrived, so it cannot be a confirm sent again that crossed it. Read that way, every
    plan's conversation ends at a_co and at a_ta; read without it, each stayed open (two
    readings, ``finished`` and ``ending``) until a_ta refused its 129th plan."""
    ends = {"a_ta": (ProtocolStates(), PART, "a_co"), "a_co": (ProtocolStates(), INIT, "a_ta")}
    coordinate = machine_of(default_spec(), "coordinate")  # declared in the specification
    for plan in range(3):
        cid = f"exec{plan}"
        wire = [
            (INIT, P.REQUEST, False, f"{cid}-rq", None),
            (PART, P.INFORM, False, f"{cid}-i1", f"{cid}-rq"),
            (INIT, P.CONFIRM, False, f"{cid}-c1", f"{cid}-i1"),
            (PART, P.INFORM, True, f"{cid}-i2", f"{cid}-c1"),
            (INIT, P.CONFIRM, False, f"{cid}-c2", f"{cid}-i2"),
        ]
        for table, local, peer in ends.values():
            for role, perf, terminal, reply_with, in_reply_to in wire:
                table.observe(
                    peer, cid, coordinate, role, perf, local_role=local, terminal=terminal,
                    reply_with=reply_with, in_reply_to=in_reply_to,
                )  # fmt: skip
            tracker = table.get(peer, cid)
            assert tracker is not None and tracker.is_finished and tracker.states == {"finished"}
            assert table.open_with(peer) == 0
    # without in-reply-to the confirm may have crossed the terminal inform: still open
    t = steps("coordinate", (INIT, P.REQUEST), (PART, P.INFORM), (INIT, P.CONFIRM))
    t.step(PART, P.INFORM, terminal=True)
    t.step(INIT, P.CONFIRM)
    assert t.states == {"finished", "ending"} and not t.is_finished


def test_the_table_forgets_finished_conversations_and_bounds_open_ones() -> None:
    table = ProtocolStates(max_open=3, max_ended=2)
    for n in range(5):
        table.observe("a_pl", f"q{n}", "fipa-query", INIT, P.QUERY_REF, local_role=PART)
        table.observe("a_pl", f"q{n}", "fipa-query", PART, P.INFORM_REF, local_role=PART)
    assert len(table) == 2 and table.open_count == 0
    assert table.get("a_pl", "q4") is not None and table.get("a_pl", "q0") is None
    for n in range(5):
        table.observe("a_pl", f"o{n}", "fipa-query", INIT, P.QUERY_REF, local_role=PART)
    assert table.open_count == 3 and table.forgotten_open == 2


def test_the_table_rolls_back_what_a_failed_step_would_have_sent() -> None:
    table = ProtocolStates()
    table.observe("a_pl", "q", "fipa-query", INIT, P.QUERY_REF, local_role=PART)
    table.commit()
    table.observe("a_pl", "q", "fipa-query", PART, P.INFORM_REF, local_role=PART)
    table.rollback()
    tracker = table.get("a_pl", "q")
    assert tracker is not None and tracker.state == "queried"


# ---- the agent -----------------------------------------------------------------------------


class Idle(Agent):
    """An agent whose behaviour does nothing: the test drives acquisition and sending."""

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("idle", lambda: None, terminal=lambda: False)])


class Km(Idle):
    name = "a_km"


class Co(Idle):
    name = "a_co"


def communicate(
    perf: Performative,
    sender: str,
    receiver: str,
    protocol: str,
    cid: str,
    content: msgspec.Struct | None = None,
    **overrides: Any,
) -> Communicate:
    """A communicate whose reply-with names its conversation and performative."""
    overrides.setdefault("reply_with", f"{cid}-{perf.value}")
    return build(perf, sender, receiver, protocol, cid, content, **overrides)


class Wire:
    """One agent on a MemoryBus, with everything it publishes collected."""

    def __init__(self, cls: type[Idle]) -> None:
        self.bus = MemoryBus()
        self.agent = cls(self.bus.transport())
        self.out: list[Communicate] = []
        self.bus.subscribe(keys.FIPA_ALL, lambda k, p: self.out.append(decode(p)))

    def deliver(self, channel: str, msg: Communicate) -> None:
        """Acquire ``msg`` as the agent's input buffer would, then dispatch the output buffer."""
        assert msg.sender is not None
        self.agent.engine.take(keys.fipa_key(channel, msg.sender.name, self.agent.name), encode(msg))
        self.agent.engine.protocol_states.commit()
        self.agent.engine.dispatch()

    def received(self) -> list[Communicate]:
        return [m for m in (r.msg for r in self.agent.engine.x)]

    def answers(self) -> list[Communicate]:
        return [m for m in self.out if m.sender is not None and m.sender.name == self.agent.name]


def km_sends(w: Wire, perf: Performative) -> None:
    """a_km sends ``perf`` in its environment subscription ``env`` to a_ta."""
    w.agent.engine.send(
        "a_ta", perf, Subscription("environment"), protocol="fipa-subscribe", conversation_id="env"
    )


def test_an_inform_before_the_agree_gets_not_understood_counted_and_logged(
    caplog: pytest.LogCaptureFixture,
) -> None:
    w = Wire(Km)
    km_sends(w, P.SUBSCRIBE)
    w.agent.engine.dispatch()
    update = WorldUpdate(stamp=1.0, objects=())
    with caplog.at_level(logging.WARNING, logger="a_km"):
        w.deliver("C6", communicate(P.INFORM, "a_ta", "a_km", "fipa-subscribe", "env", update))
    (nu,) = [m for m in w.answers() if m.performative is P.NOT_UNDERSTOOD]
    assert nu.conversation_id == "env" and nu.receiver[0].name == "a_ta"
    assert nu.content.decode() == (
        "fipa-subscribe: the participant may not send 'inform' in state 'subscribed'; allowed: "
        "initiator cancel, initiator not-understood, participant agree, participant not-understood, "
        "participant refuse"
    )
    assert w.agent.counters["protocol_violations"] == 1 and not w.agent.engine.x
    assert any("conversation env" in r.getMessage() and r.levelno == logging.WARNING for r in caplog.records)


def test_a_second_agree_and_an_inform_in_a_conversation_never_opened_are_refused() -> None:
    w = Wire(Km)
    km_sends(w, P.SUBSCRIBE)
    w.agent.engine.dispatch()
    w.deliver("C6", communicate(P.AGREE, "a_ta", "a_km", "fipa-subscribe", "env"))
    # a second agree (not a byte-identical copy: that is dropped as a duplicate, below)
    w.deliver("C6", communicate(P.AGREE, "a_ta", "a_km", "fipa-subscribe", "env", reply_with="again"))
    update = WorldUpdate(stamp=1.0, objects=())
    w.deliver("C6", communicate(P.INFORM, "a_ta", "a_km", "fipa-subscribe", "other", update))
    refused = [m for m in w.answers() if m.performative is P.NOT_UNDERSTOOD]
    assert [m.conversation_id for m in refused] == ["env", "other"]
    assert "may not send 'agree' in state 'active'" in refused[0].content.decode()
    assert refused[1].content.decode().startswith("no such conversation of a_km with a_ta")
    assert w.agent.counters["protocol_violations"] == 2
    assert [m.performative for m in w.received()] == [P.AGREE]


def test_an_initiator_out_of_turn_in_coordinate_is_refused() -> None:
    class Ta(Idle):
        name = "a_ta"

    w = Wire(Ta)
    status = SWStatus(state=SWState.RUNNING)
    w.deliver("C1", communicate(P.CONFIRM, "a_co", "a_ta", "coordinate", "exec1", status))
    (nu,) = w.answers()
    assert nu.performative is P.NOT_UNDERSTOOD
    why = nu.content.decode()
    assert "no such conversation" in why and "'confirm' in state 'start'" in why


@pytest.mark.parametrize(
    ("ontology", "why"),
    [(None, "language L_WM needs ontology O_RoCo, not None"), ("SUMO", "not SUMO")],
)
def test_a_communicate_without_the_languages_ontology_gets_not_understood(
    ontology: str | None, why: str
) -> None:
    w = Wire(Km)
    query = communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q", ObjectQuery("jar"), ontology=ontology)
    w.deliver("C4", query)
    (nu,) = w.answers()
    assert nu.performative is P.NOT_UNDERSTOOD and why in nu.content.decode()
    assert not w.agent.engine.x and w.agent.counters["rejected"] == 1


def test_the_runtime_refuses_what_fipa_forbids_live_and_counts_it() -> None:
    """The sequences ``roco spec verify`` flags (tests/spec_check/test_forbidden_conversations.py)
    are refused live: a query asked again in its answered conversation and a second query in an
    open one get not-understood; an initiator's not-understood before it received anything is
    counted and not answered (no not-understood answers one); a byte-identical copy is a
    retransmission, taken once and not refused."""
    w = Wire(Km)
    query = communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q", ObjectQuery("jar"))
    w.deliver("C4", query)
    (item,) = list(w.agent.engine.x)
    w.agent.engine.reply(item, P.INFORM_REF, Answer())
    w.agent.engine.x.clear()
    w.deliver("C4", query)  # the same bytes again: a copy, not a new opening
    assert not w.agent.engine.x and w.agent.counters["protocol_violations"] == 0
    again = communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q", ObjectQuery("jar"), reply_with="q-2")
    w.deliver("C4", again)
    second = communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "r", ObjectQuery("jar"))
    w.deliver("C4", second)
    w.deliver(
        "C4",
        communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "r", ObjectQuery("jar"), reply_with="r-2"),
    )
    refusals = [m for m in w.answers() if m.performative is P.NOT_UNDERSTOOD]
    assert [m.conversation_id for m in refusals] == ["q", "r"], refusals
    assert all("new conversation-id" in m.content.decode() for m in refusals)
    nu = communicate(P.NOT_UNDERSTOOD, "a_pl", "a_km", "fipa-query", "s", encoding="utf-8")
    w.deliver("C4", communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "s", ObjectQuery("jar")))
    w.deliver("C4", nu)
    assert w.agent.counters["protocol_violations"] == 3
    assert len([m for m in w.answers() if m.performative is P.NOT_UNDERSTOOD]) == 2


def test_sending_out_of_the_protocol_state_raises_and_is_counted() -> None:
    w = Wire(Km)
    with pytest.raises(SpecViolation, match="no such conversation of a_km with a_pl"):
        w.agent.engine.send("a_pl", P.INFORM_REF, Answer(), protocol="fipa-query", conversation_id="q")
    w.deliver("C4", communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q", ObjectQuery("jar")))
    (item,) = list(w.agent.engine.x)
    w.agent.engine.reply(item, P.INFORM_REF, Answer())
    with pytest.raises(SpecViolation, match="already ended in state 'answered'"):
        w.agent.engine.reply(item, P.INFORM_REF, Answer())
    with pytest.raises(SpecViolation, match="may not send 'agree'"):
        w.agent.engine.reply(item, P.AGREE)
    assert w.agent.counters["send_violations"] == 3
    w.agent.engine.dispatch()
    assert [m.performative for m in w.answers()] == [P.INFORM_REF]  # nothing refused was sent


def test_a_cancel_that_crossed_the_outcome_reaches_the_agent_and_may_be_answered() -> None:
    w = Wire(Co)
    command = HumanCommand(text="pour", goal=TaskAtom("pour", ("jar", "bowl")))
    request = communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd", command)
    w.deliver("C2", request)
    item = w.agent.engine.x.popleft()
    w.agent.engine.reply(item, P.AGREE)
    w.agent.engine.reply(item, P.INFORM, CommandOutcome(command_id="cmd", succeeded=True))
    w.agent.engine.dispatch()
    w.deliver("C2", communicate(P.CANCEL, "a_hi", "a_co", "fipa-request", "cmd"))
    (cancel,) = list(w.agent.engine.x)
    assert cancel.performative is P.CANCEL and w.agent.counters["crossings"] == 1
    w.agent.engine.fail(cancel, P.FAILURE, "no such command (it may have ended already)")
    w.agent.engine.dispatch()
    assert [m.performative for m in w.answers()] == [P.AGREE, P.INFORM, P.FAILURE]
    assert w.agent.counters["protocol_violations"] == 0


def test_a_cancel_of_a_conversation_the_agent_never_saw_reaches_it() -> None:
    w = Wire(Co)
    w.deliver("C2", communicate(P.CANCEL, "a_hi", "a_co", "fipa-request", "gone"))
    (cancel,) = list(w.agent.engine.x)
    w.agent.engine.fail(cancel, P.FAILURE, "no such command")
    assert w.agent.counters["protocol_violations"] == 0


def test_after_a_not_understood_only_what_crossed_it_belongs_to_the_conversation() -> None:
    """a_ta answers a_km's subscribe not-understood: a_km's cancel, sent before it saw that,
    still belongs there; a new subscribe under the same conversation-id does not (a
    conversation-id names one conversation, FIPA SC00061): the runtime refuses to send it."""
    w = Wire(Km)
    km_sends(w, P.SUBSCRIBE)
    w.agent.engine.dispatch()
    w.deliver("C6", communicate(P.NOT_UNDERSTOOD, "a_ta", "a_km", "fipa-subscribe", "env", encoding="utf-8"))
    km_sends(w, P.CANCEL)
    with pytest.raises(SpecViolation, match="new conversation-id"):
        km_sends(w, P.SUBSCRIBE)
    tracker = w.agent.engine.protocol_states.get("a_ta", "env")
    assert tracker is not None and tracker.is_finished and tracker.aborted_by == PARTICIPANT
    assert w.agent.counters["send_violations"] == 1


class Replier(Km):
    """Answers each query, then raises once after answering: the answer is dropped with the
    output buffer, and its protocol step is undone with it."""

    def build_fsm(self) -> FSM:
        self.raised = False
        return FSM([Behaviour("serve", self._serve, terminal=lambda: False)])

    def _serve(self) -> None:
        for item in list(self.engine.x):
            self.engine.reply(item, P.INFORM_REF, Answer())
            if not self.raised:
                self.raised = True
                raise RuntimeError("a bug after the reply")
            self.engine.x.remove(item)
            self.engine.stop()


def test_a_failing_transition_function_takes_back_its_protocol_steps() -> None:
    bus = MemoryBus()
    agent = Replier(bus.transport())
    answers: list[Communicate] = []
    bus.subscribe(keys.inbox_key("a_pl"), lambda k, p: answers.append(decode(p)))
    agent.engine.bind()
    query = communicate(P.QUERY_REF, "a_pl", "a_km", "fipa-query", "q", ObjectQuery("jar"))
    bus.publish(keys.fipa_key("C4", "a_pl", "a_km"), encode(query))
    agent.engine.run()  # first step raises after replying; the retry replies again and stops
    assert agent.counters["behaviour_errors"] == 1 and agent.counters["send_violations"] == 0
    assert [m.performative for m in answers] == [P.INFORM_REF]


def _state_of(t: CrossingTracker) -> dict[str, object]:
    """Every data attribute of ``t`` (compiled by mypyc or not: read through ``dir``)."""
    return {a: getattr(t, a) for a in dir(t) if not a.startswith("_") and not callable(getattr(t, a))}


def test_a_copy_of_a_tracker_holds_all_its_state_and_is_independent() -> None:
    """``copy`` lists the attributes one by one (a compiled class has no ``__dict__``): a new
    attribute it forgets makes the copy differ here."""
    t, _ = follow(None, "fipa-subscribe", INITIATOR, Performative.SUBSCRIBE, local_role=INITIATOR)
    t.step(PARTICIPANT, Performative.AGREE)
    t.crossings, t.initiator_heard, t.participant_heard = 3, True, True
    t.abort(PARTICIPANT)
    t.latest_initiator, t.latest_participant = "s1", "a1"
    copy = t.copy()
    assert _state_of(copy) == _state_of(t)
    copy.step(PARTICIPANT, Performative.INFORM)
    assert copy.messages == t.messages + 1 and copy.readings != t.readings
