"""a_ta passes the robot's watch on (services/agents/task_executor/watching.py): a_km's
``Subscription`` of topic ``watch`` on C6 is agreed and becomes a fipa-subscribe to ag_ex on C5
(L_EX ``Watch``); each frame ag_ex informs (an L_SD ``Observation``) goes to a_km as an
observation, and a_ta asks ag_ex nothing for it (a watched frame is no look of the plan);
a_km's cancel cancels it at ag_ex; a period out of range is refused. The agent is driven by
hand (tests/runtime/test_reliability.py ``Wire``)."""

from __future__ import annotations

import msgspec

from services.agents.task_executor.agent import TaskExecutor
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Performative as P
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import PowerOns, Watch
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_wm import Subscription, WorldUpdate
from tests.agents.test_task_retreat import ag_ex_answers
from tests.agents.test_task_subscription import observe_request, subscribe, updates
from tests.runtime.test_reliability import Wire
from tests.support.messages import communicate

KNOCKED = (0.0, 1.0, 0.0, 0.0)  # upside down: 180° about x


def _km_watch(w: Wire[TaskExecutor], cid: str, sub: Subscription, perf: P = P.SUBSCRIBE) -> None:
    w.deliver(communicate(perf, "a_km", "a_ta", "fipa-subscribe", cid, sub, reply_with=f"{cid}-{perf.value}"))
    w.step("idle")


def _to_ex(w: Wire[TaskExecutor], perf: P) -> list[tuple[str | None, object]]:
    return [
        (m.conversation_id, msgspec.msgpack.decode(m.content, type=Watch | PowerOns) if m.content else None)
        for m in w.mine(perf)
        if m.receiver[0].name == "ag_ex"
        and m.protocol == "fipa-subscribe"
        and m.conversation_id != "ta-power-ons"
    ]


def test_a_watch_a_km_asks_for_reaches_ag_ex_and_its_frames_reach_a_km_only() -> None:
    bus = MemoryBus()
    w = Wire(TaskExecutor, bus)
    w.agent.setup()
    ag_ex = bus.transport()
    ag_ex.announce(keys.alive_key("ag_ex"))  # the role subscribes to ag_ex once it is there
    w.agent.engine.acquire()
    subscribe(w, "km-env")
    ag_ex_answers(w, observe_request(w), Observation(stamp=1.0, objects=()))
    w.step("idle")
    requests = len(w.mine(P.REQUEST))
    _km_watch(w, "km-watch", Subscription("watch", period_s=0.25))
    agreed = [m for m in w.mine(P.AGREE) if m.conversation_id == "km-watch"]
    assert len(agreed) == 1
    ((cid, watch),) = _to_ex(w, P.SUBSCRIBE)
    assert watch == Watch(objects=(), period_s=0.25)
    sub = next(m for m in w.mine(P.SUBSCRIBE) if m.conversation_id == cid)
    w.deliver(communicate(P.AGREE, "ag_ex", "a_ta", "fipa-subscribe", cid, in_reply_to=sub.reply_with))
    frame = Observation(
        stamp=7.5, objects=(ObjectObservation(name="bowl", pose=Pose((0.6, 0.1, 0.9), KNOCKED)),)
    )
    w.deliver(
        communicate(P.INFORM, "ag_ex", "a_ta", "fipa-subscribe", cid, frame, in_reply_to=sub.reply_with)
    )
    w.step("idle")
    assert _to_ex(w, P.CANCEL) == []  # ag_ex's agree is the watch's, not a power-ons attempt's
    last = updates(w, "km-env")[-1]
    assert isinstance(last, WorldUpdate) and last.stamp == 7.5
    assert last.objects[0].name == "bowl" and last.objects[0].pose == frame.objects[0].pose
    assert len(w.mine(P.REQUEST)) == requests  # no command, no look of a_ta's own for it
    assert w.agent.counters["handler_errors"] == 0
    _km_watch(w, "km-watch", Subscription("watch", period_s=0.25), P.CANCEL)
    assert _to_ex(w, P.CANCEL) == [(cid, Watch(objects=(), period_s=0.25))]
    assert w.agent.watching.asked_by is None


def test_a_watch_period_out_of_range_is_refused_and_ag_ex_not_asked() -> None:
    w = Wire(TaskExecutor)
    w.agent.setup()
    _km_watch(w, "km-watch", Subscription("watch", period_s=0.01))
    (refused,) = [m for m in w.mine(P.REFUSE) if m.conversation_id == "km-watch"]
    assert "a watch period is 0.1..5.0 s" in refused.content.decode()
    assert _to_ex(w, P.SUBSCRIBE) == []
