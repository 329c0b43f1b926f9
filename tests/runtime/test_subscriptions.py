"""The subscription a fipa-subscribe initiator role keeps open itself
(services/runtime/roles/subscriptions.py, FIPA SC00035), a repeated opening recognised by the
participant role (services/runtime/roles/, FIPA SC00061 §2.4), and the conversations a role
declared with ``keep`` keeps across a restart (services/runtime/state_store.py). The agents are driven by hand
on a MemoryBus, as in test_reliability.py; time is moved by setting the next attempt's time."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

from services.agents.coordinator.agent import Coordinator
from services.agents.human_interface.agent import CommandNote, HumanInterface
from services.agents.knowledge.agent import KnowledgeManager
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.runtime.state_store import ENV_STATE_DIR, KeptConversations
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import HumanCommand, Progress, ProgressSubscription, TaskAtom, TaskState
from shared.fipa_codec.languages.l_wm import Subscription
from tests.runtime.test_reliability import Wire, a_hi_that_sent_the_pour
from tests.support.messages import communicate

P = Performative


def _answer(
    w: Wire[HumanInterface],
    perf: Performative,
    cid: str,
    reply_with: str | None,
    term: msgspec.Struct | None = None,
) -> None:
    w.deliver(communicate(perf, "a_co", "a_hi", "fipa-subscribe", cid, term, in_reply_to=reply_with))
    w.step("interact")


def _tick(w: Wire[HumanInterface]) -> None:
    """Take in what arrived (a token's change, a due attempt) and dispatch what that sent."""
    w.agent.engine.acquire()
    w.agent.engine.dispatch()


def _subscribes(w: Wire[HumanInterface]) -> list[tuple[str | None, str | None]]:
    return [(m.conversation_id, m.reply_with) for m in w.mine(P.SUBSCRIBE)]


def test_a_his_subscription_waits_for_a_co_backs_off_and_cancels_a_late_agree() -> None:
    bus = MemoryBus()
    hi = Wire(HumanInterface, bus)
    hi.agent.setup()
    hi.step("interact")
    assert not hi.mine(P.SUBSCRIBE)  # a_co's token is not there: nothing sent into the void
    co = bus.transport()
    co.announce(keys.alive_key("a_co"))
    _tick(hi)
    ((cid, rw),) = _subscribes(hi)
    sub = hi.agent.progress
    assert cid == "hi-progress" and sub.pending and not sub.subscribed
    pending = hi.agent.engine.pending_replies.get(rw or "")
    assert pending is not None
    pending.deadline = 0.0  # a_co did not answer in time
    hi.agent.engine.pending_replies.expect(pending)  # moved by hand: expected again, so it is looked at
    _tick(hi)
    hi.step("interact")
    assert not sub.pending and sub.retry_at is not None and len(_subscribes(hi)) == 1
    sub.retry_at = 0.0  # the first interval has passed
    _tick(hi)
    (_, (cid2, rw2)) = _subscribes(hi)
    assert cid2 == "hi-progress-2" and sub.interval == 2 * sub.retry_s[0]  # doubled
    _answer(hi, P.REFUSE, "hi-progress-2", rw2)
    sub.retry_at = 0.0
    _tick(hi)
    (*_, (cid3, rw3)) = _subscribes(hi)
    assert cid3 == "hi-progress-3" and sub.interval == min(4 * sub.retry_s[0], sub.retry_s[1])
    _answer(hi, P.AGREE, "hi-progress", rw)  # the first attempt agrees late: superfluous
    (cancel,) = hi.mine(P.CANCEL)
    assert cancel.conversation_id == "hi-progress" and not sub.subscribed
    _answer(hi, P.AGREE, "hi-progress-3", rw3)
    assert sub.subscribed and sub.interval == sub.retry_s[0] and sub.conversation_id == "hi-progress-3"
    progress = Progress(command_id="cmd-x", state=TaskState.WAITING)
    _answer(hi, P.INFORM, "hi-progress-3", rw3, progress)  # the stream reaches the agent's handler
    _answer(hi, P.INFORM, "hi-progress", cancel.reply_with)  # the cancel's answer does not
    assert hi.agent.counters["handler_errors"] == 0
    co.close()  # a_co goes away: the subscription pauses, the attempts go on
    _tick(hi)
    assert not sub.subscribed and sub.retry_at is not None
    co = bus.transport()
    co.announce(keys.alive_key("a_co"))  # ... and is back before the next attempt: one at once
    _tick(hi)
    assert [c for c, _ in _subscribes(hi)][-1] == "hi-progress-4" and sub.pending


def test_a_restarted_agent_subscribes_in_a_conversation_its_earlier_process_did_not_open(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where the agent keeps state (ROCO_STATE_DIR), the count of attempts is kept: a_km killed
    after its second attempt and started again opens the third, not its first's conversation
    again (which the peer still serves: an opening in an open conversation, FIPA SC00061)."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    bus = MemoryBus()
    km = Wire(KnowledgeManager, bus)
    km.agent.setup()
    km.agent.engine.dispatch()
    ((cid, rw),) = [(m.conversation_id, m.reply_with) for m in km.mine(P.SUBSCRIBE)]
    km.deliver(communicate(P.REFUSE, "a_ta", "a_km", "fipa-subscribe", cid, in_reply_to=rw))
    km.step("idle")
    assert [m.conversation_id for m in km.mine(P.SUBSCRIBE)] == ["km-environment", "km-environment-2"]
    again = Wire(KnowledgeManager, MemoryBus())  # the restarted process
    again.agent.setup()
    again.agent.engine.dispatch()
    assert [m.conversation_id for m in again.mine(P.SUBSCRIBE)] == ["km-environment-3"]
    assert (tmp_path / "a_km.subscriptions.json").is_file()


def test_a_kms_subscription_goes_at_start_again_at_once_and_when_a_ta_is_back() -> None:
    bus = MemoryBus()
    km = Wire(KnowledgeManager, bus)
    km.agent.setup()
    km.agent.engine.dispatch()
    ((cid, rw),) = [(m.conversation_id, m.reply_with) for m in km.mine(P.SUBSCRIBE)]
    assert cid == "km-environment"
    km.deliver(communicate(P.REFUSE, "a_ta", "a_km", "fipa-subscribe", cid, in_reply_to=rw))
    km.step("idle")
    (_, (cid2, rw2)) = [(m.conversation_id, m.reply_with) for m in km.mine(P.SUBSCRIBE)]
    assert cid2 == "km-environment-2" and rw2 != rw  # at once, in a conversation of its own
    km.deliver(communicate(P.AGREE, "a_ta", "a_km", "fipa-subscribe", cid2, in_reply_to=rw2))
    km.step("idle")
    assert km.agent.environment.subscribed
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))
    km.agent.engine.acquire()
    km.agent.engine.dispatch()
    assert len(km.mine(P.SUBSCRIBE)) == 2  # its first appearance: the subscription stands
    ta.close()
    km.agent.engine.acquire()
    assert not km.agent.environment.subscribed
    km.agent.engine.dispatch()
    assert len(km.mine(P.SUBSCRIBE)) == 2  # away: it waits for a_ta
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))
    km.agent.engine.acquire()
    km.agent.engine.dispatch()
    # back: a restarted a_ta has lost it; one that kept it is told to stop serving it (cancel)
    assert [m.conversation_id for m in km.mine(P.SUBSCRIBE)][-1] == "km-environment-3"
    (cancel,) = km.mine(P.CANCEL)
    assert cancel.conversation_id == "km-environment-2"
    assert km.agent.counters["send_violations"] == 0


def test_one_role_keeps_two_subscriptions_apart_and_unsubscribe_ends_one() -> None:
    """a_km keeps its environment subscription and a watch (L_WM ``Subscription`` topic
    ``watch``) in the one C6 fipa-subscribe role: each answer reaches the subscription whose
    conversation it is in (``StandingSubscription.owns``), ``Roles.unsubscribe`` cancels the
    watch's attempt and no other follows, and a second subscription of a kept conversation-id
    is refused."""
    km = Wire(KnowledgeManager)
    km.agent.setup()
    km.agent.engine.dispatch()
    env = km.agent.environment
    watch = km.agent.roles.subscribe(
        "C6",
        "fipa-subscribe",
        Subscription("watch", period_s=0.25),
        conversation_id="km-watch",
        at_start=True,
    )
    km.agent.engine.dispatch()
    sent = {m.conversation_id: m.reply_with for m in km.mine(P.SUBSCRIBE)}
    assert set(sent) == {"km-environment", "km-watch"}
    km.deliver(
        communicate(P.AGREE, "a_ta", "a_km", "fipa-subscribe", "km-watch", in_reply_to=sent["km-watch"])
    )
    km.step("idle")
    assert watch.subscribed and not env.subscribed  # the watch's agree is the watch's alone
    km.deliver(
        communicate(
            P.AGREE, "a_ta", "a_km", "fipa-subscribe", "km-environment", in_reply_to=sent["km-environment"]
        )
    )
    km.step("idle")
    assert env.subscribed
    with pytest.raises(KeyError, match="keeps the subscription km-watch"):
        km.agent.roles.subscribe("C6", "fipa-subscribe", Subscription("watch"), conversation_id="km-watch")
    km.agent.roles.unsubscribe(watch)
    km.agent.engine.dispatch()
    (cancel,) = km.mine(P.CANCEL)
    assert cancel.conversation_id == "km-watch" and not watch.subscribed and watch.retry_at is None
    assert env.subscribed  # the other subscription of the role stands
    watch.retry_at = 0.0  # were an attempt due, none is made: the role keeps it no more
    km.agent.engine.acquire()
    km.agent.engine.dispatch()
    assert [m.conversation_id for m in km.mine(P.SUBSCRIBE)].count("km-watch") == 1
    km.agent.roles.unsubscribe(watch)  # not kept: nothing
    assert len(km.mine(P.CANCEL)) == 1


def test_a_role_that_keeps_no_subscription_refuses_to_keep_one() -> None:
    co = Wire(Coordinator)
    with pytest.raises(KeyError, match="no resubscribing initiator role"):
        co.agent.roles.subscribe("C2", "fipa-subscribe", ProgressSubscription(), conversation_id="x")


def test_a_repeated_request_is_answered_again_by_the_role_not_handed_to_the_agent() -> None:
    co = Wire(Coordinator)
    pour = HumanCommand(text="pour the jar into the bowl", goal=TaskAtom("pour", ("jar", "bowl")))
    co.deliver(communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", pour, reply_with="r1"))
    co.step("procReq")
    (agree,) = co.mine(P.AGREE)
    # the same request (reply-with r1 from a_hi), not byte-identical (a different reply-by)
    co.deliver(
        communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", pour, reply_with="r1", reply_by=4.1e9)
    )
    co.step("procReq")
    assert co.agent.counters["repeated_requests"] == 1 and not co.mine(P.REFUSE)
    assert [m.reply_with for m in co.mine(P.AGREE)] == [agree.reply_with] * 2  # its agree again
    assert list(co.agent.tasks) == ["cmd-1"]


# ---- the conversations a role keeps across a restart (keep=) --------------------------------


def test_kept_conversations_come_back_with_their_note_and_what_cannot_is_dropped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """a_hi's fipa-request role keeps its open commands (``keep=CommandNote``): the runtime
    writes each (opening, state, note) and takes it back when a new a_hi is built; a record
    whose note does not decode, or of a role that keeps nothing, is dropped with a warning."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    _bus, _reports, first, request = a_hi_that_sent_the_pour("req-9")
    kept = msgspec.json.decode((tmp_path / "a_hi.json").read_bytes(), type=KeptConversations)
    (record,) = kept.conversations
    assert (record.channel, record.protocol, record.state) == ("C2", "fipa-request", "requested")
    assert msgspec.json.decode(record.data, type=CommandNote) == CommandNote(
        request_id="req-9", label=first.agent.commands[request.conversation_id or ""].label
    )
    bad_note = msgspec.structs.replace(record, data=msgspec.Raw(b'{"label": 3}'))
    no_keep = msgspec.structs.replace(record, channel="C7", protocol="fipa-query")
    (tmp_path / "a_hi.json").write_bytes(
        msgspec.json.encode(KeptConversations(conversations=[bad_note, no_keep, record]))
    )
    caplog.clear()
    second = Wire(HumanInterface)
    assert list(second.agent.commands) == [request.conversation_id]
    dropped = [r.getMessage() for r in caplog.records if "cannot be taken back" in r.getMessage()]
    assert len(dropped) == 2, dropped
    note = second.agent.commands[request.conversation_id or ""].note
    assert note.request_id == "req-9" and not note.agreed


def test_resume_in_names_a_state_the_protocol_can_take_a_conversation_back_in() -> None:
    """``resume_in`` (a_ta's plan: coordinate's ``running``) is for a participant role that
    keeps its conversations, and must name a state of its protocol that communicates lead to
    and end nothing in (not the initial state, not a final one, not coordinate's ``ending``,
    reached by a final report only): checked
    when the role is declared, and with the roles' comparison with the specification that
    refuses to start the agent (``roco spec verify-code``)."""
    from services.agents.task_executor.agent import TaskExecutor
    from services.runtime.roles import handlers_of, participant, role_problems
    from services.spec.model import default_spec

    with pytest.raises(ValueError, match="resume_in is for a participant role declared with keep"):
        participant("C1", "coordinate", "L_HFSM", "L_SW", resume_in="running")
    spec, handlers = default_spec(), list(handlers_of(TaskExecutor))
    assert role_problems(spec, "a_ta", TaskExecutor.ROLES, handlers) == []
    for state in ("runing", "finished", "ending", "start"):
        roles = [
            participant(
                "C1", "coordinate", "L_HFSM", "L_SW", keep=True, resume_in=state, confirmed_informs=True
            ),
            *TaskExecutor.ROLES[1:],
        ]
        assert role_problems(spec, "a_ta", roles, handlers) == [
            f"agent a_ta takes its kept coordinate conversations on C1 back in {state!r}, which is "
            "no state of [protocols.coordinate] to take one back in (one of: reported, requested, "
            "running)"
        ]
