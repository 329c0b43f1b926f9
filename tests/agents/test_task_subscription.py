"""a_ta's side of a_km's fipa-subscribe (C6): every new subscription, also one from a
restarted a_km that may have missed updates in flight, gets the last asserted change of each
object and then a fresh observation (services/agents/task_executor/agent.py, docs/recovery.md)."""

from __future__ import annotations

import time
from pathlib import Path

import msgspec
import pytest

from services.agents.task_executor.agent import INITIAL_OBSERVE_RETRY_S, TaskExecutor
from services.runtime.state_store import ENV_STATE_DIR
from shared.fipa_codec import Communicate
from shared.fipa_codec import Performative as P
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Observe
from shared.fipa_codec.languages.l_hfsm import Assert
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_wm import ObjectUpdate, Subscription, WorldUpdate
from tests.agents.test_task_retreat import ag_ex_answers
from tests.runtime.test_reliability import Wire
from tests.support.messages import communicate


def subscribe(w: Wire[TaskExecutor], conversation: str) -> None:
    w.deliver(
        communicate(
            P.SUBSCRIBE,
            "a_km",
            "a_ta",
            "fipa-subscribe",
            conversation,
            Subscription(),
            reply_with=conversation,
        )
    )
    w.step("idle")


def observe_request(w: Wire[TaskExecutor]) -> Communicate:
    last = [m for m in w.mine(P.REQUEST) if m.receiver[0].name == "ag_ex"][-1]
    assert msgspec.msgpack.decode(last.content, type=Observe) == Observe()
    return last


def updates(w: Wire[TaskExecutor], conversation: str) -> list[WorldUpdate]:
    return [
        msgspec.msgpack.decode(m.content, type=WorldUpdate)
        for m in w.mine(P.INFORM)
        if m.receiver[0].name == "a_km" and m.conversation_id == conversation
    ]


def scene(stamp: float, x: float) -> Observation:
    return Observation(
        stamp=stamp, objects=(ObjectObservation(name="jar", pose=Pose((x, 0.2, 0.9)), particles_inside=18),)
    )


@pytest.mark.requirement("R3.2")
def test_a_new_subscription_gets_the_asserted_changes_then_a_fresh_observation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    w = Wire(TaskExecutor)
    w.agent.setup()
    subscribe(w, "km-1")
    ag_ex_answers(w, observe_request(w), scene(1.0, 0.8))
    w.step("idle")
    (first,) = updates(w, "km-1")
    assert first.stamp == 1.0 and first.objects[0].pose == Pose((0.8, 0.2, 0.9))
    # the plan's symbolic changes: the jar taken from the cabinet, then put on the table
    w.agent._assert(Assert(subject="jar", relation="heldBy", object="right_gripper"))
    w.agent._assert(Assert(subject="jar", relation="on", object="table"))
    w.agent.engine.dispatch()
    assert len(updates(w, "km-1")) == 3
    n_requests = len(w.mine(P.REQUEST))

    subscribe(w, "km-2")  # a_km restarted: its store may miss any of these
    assert [m.conversation_id for m in w.mine(P.AGREE)] == ["km-1", "km-2"]
    (asserted,) = updates(w, "km-2")
    assert asserted.stamp < 0
    assert asserted.objects == (ObjectUpdate(name="jar", location="table", relation="on", held_by=""),)
    assert len(w.mine(P.REQUEST)) == n_requests + 1  # observed anew for the new subscriber
    ag_ex_answers(w, observe_request(w), scene(7.5, 0.55))
    w.step("idle")
    fresh = updates(w, "km-2")[-1]
    assert fresh.stamp == 7.5 and fresh.objects[0].pose == Pose((0.55, 0.2, 0.9))
    assert fresh.objects[0].particles == 18
    assert len(updates(w, "km-1")) == 3  # nothing more into the old conversation


def test_a_late_answer_to_an_earlier_initial_observe_is_taken(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Seen under load: each Observe took longer than the initial observe's short deadline, so
    a restarted a_ta asked again every 3 s and ignored every answer as late, for 10 minutes. An
    answer to any of the initial observes it asked will do."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    w = Wire(TaskExecutor)
    w.agent.setup()
    subscribe(w, "km-1")
    first = observe_request(w)
    real = time.time
    later = lambda: real() + INITIAL_OBSERVE_RETRY_S + 1.0  # noqa: E731
    monkeypatch.setattr(time, "time", later)
    monkeypatch.setattr(w.agent.sources, "time", later)  # the agent's clock (services/runtime/sources.py)
    w.step("idle")  # the deadline passes: a local failure …
    w.step("idle")  # … and a_ta asks again
    second = observe_request(w)
    assert second.conversation_id != first.conversation_id
    ag_ex_answers(w, first, scene(1.0, 0.8))  # the first one's answer, late
    w.step("idle")
    (taken,) = updates(w, "km-1")
    assert taken.stamp == 1.0
    ag_ex_answers(w, second, scene(2.0, 0.8))  # the second one's, now not needed
    w.step("idle")
    assert len(updates(w, "km-1")) == 1
