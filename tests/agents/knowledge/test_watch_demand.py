"""a_km has the robot watch while a scene subscriber needs changes quickly
(services/agents/knowledge/watch_demand.py): a ``SceneSubscription`` with ``within_s`` makes
a_km subscribe a ``Subscription`` of topic ``watch`` to a_ta on C6 (half the shortest
``within_s``, bounded), cancelled when the last such subscriber cancels; one without it asks
nothing. a_km and the subscriber run on a MemoryBus (tests/agents/knowledge/
test_scene_subscription.py); the test plays a_ta."""

from __future__ import annotations

import queue
import time
from pathlib import Path

import pytest

from services.agents.knowledge.watch_demand import PERIOD_RANGE_S, period_for
from services.runtime import keys
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_wm import SceneSubscription, Subscription
from tests.agents.knowledge.test_agent import Peer
from tests.agents.knowledge.test_scene_subscription import (
    TIMEOUT_S,
    WT_CHANNEL,
    Subscriber,
    running_km,
    watcher_spec,
)


def test_the_period_is_half_the_shortest_within_bounded() -> None:
    assert period_for([SceneSubscription(), SceneSubscription(within_s=None)]) is None
    assert period_for([SceneSubscription(within_s=2.0), SceneSubscription(within_s=0.5)]) == 0.25
    assert period_for([SceneSubscription(within_s=0.1)]) == PERIOD_RANGE_S[0]
    assert period_for([SceneSubscription(within_s=60.0)]) == PERIOD_RANGE_S[1]


def _watch_asks(peer: Peer, wait_s: float) -> list[tuple[Communicate, Subscription | None]]:
    """What a_km sent a_ta on C6 but its environment subscription (which it repeats while
    nobody agrees), up to a cancel: what came within ``wait_s`` s (0: what has come)."""
    out: list[tuple[Communicate, Subscription | None]] = []
    deadline = time.monotonic() + wait_s
    while True:
        left = deadline - time.monotonic()
        try:
            msg = peer.subscribes.get(timeout=left) if left > 0 else peer.subscribes.get_nowait()
        except queue.Empty:
            return out
        content = decode_content(msg.language, msg.content) if msg.language else None
        sub = content if isinstance(content, Subscription) else None
        if (msg.conversation_id or "").startswith("km-environment"):
            continue  # km-environment, km-environment-2, ...: each repeat has its own id
        out.append((msg, sub))
        if msg.performative is Performative.CANCEL:
            return out


@pytest.mark.walkthrough
def test_a_subscriber_within_a_time_has_the_robot_watch_until_it_cancels(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        peer, wt = Peer(bus), Subscriber(bus, WT_CHANNEL, "a_wt")
        bus.transport().announce(keys.alive_key("a_ta"))  # a_km asks a_ta once it is there
        watched = SceneSubscription(objects=("bowl",), tilted=1.0, within_s=0.5)
        performative, _ = wt.subscribe(watched, "w1")
        assert performative is Performative.AGREE
        wt.send(Performative.CANCEL, watched, "w1")
        asks = _watch_asks(peer, TIMEOUT_S)
        assert [m.performative for m, _ in asks] == [Performative.SUBSCRIBE, Performative.CANCEL], asks
        (subscribe, sub), (cancel, _) = asks
        assert sub == Subscription("watch", period_s=0.25)
        assert cancel.conversation_id == subscribe.conversation_id and subscribe.receiver[0].name == "a_ta"
        assert km.watch_demand.period_s is None


@pytest.mark.walkthrough
def test_a_subscriber_with_no_time_asks_no_watch_and_an_impossible_time_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        peer, wt = Peer(bus), Subscriber(bus, WT_CHANNEL, "a_wt")
        performative, reason = wt.subscribe(SceneSubscription(within_s=0.05), "w0")
        assert performative is Performative.REFUSE and "within_s must be 0.2..10.0 s" in str(reason)
        performative, _ = wt.subscribe(SceneSubscription(objects=("bowl",)), "w1")
        assert performative is Performative.AGREE
        wt.send(Performative.CANCEL, SceneSubscription(objects=("bowl",)), "w1")
        # the cancel answered: a_km took both in, and what it sent a_ta before has come
        assert wt.next()[0] is Performative.INFORM
        assert _watch_asks(peer, 0) == [] and km.watch_demand.subscription is None
