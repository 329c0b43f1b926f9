"""a_km serves subscriptions to changes of the scene (L_WM ``SceneSubscription``,
``SceneChange``; FIPA SC00035) on every channel where the specification makes it the
participant of fipa-subscribe: here C7 (a_hi, the shipped specification) and the next free
channel (a_wt, the kitchen watcher of docs/spec.md's walk-through). The tests play the
subscribers and a_ta on a MemoryBus; a_km takes its inputs in order, so the answer to a query
sent after an update comes after every inform that update caused (the bus delivers in order):
that is how a test knows an inform did not come."""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import msgspec
import pytest

from services.agents.knowledge import scene_watch
from services.agents.knowledge.agent import KnowledgeManager
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.spec.model import DEFAULT_SPEC, SystemSpec, load
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import (
    ObjectUpdate,
    SceneChange,
    SceneSubscription,
    Subscription,
    WorldUpdate,
)
from tests.agents.knowledge.scene_watcher import Watcher
from tests.agents.knowledge.test_agent import Peer
from tests.spec_check.walkthrough import NEXT, entries, group_edit, snippet, staged

TIMEOUT_S = 10.0
WT_CHANNEL = NEXT.channel_name
"""The walk-through's channel from a_wt to a_km: the next free number of the shipped specification."""
UPRIGHT = (1.0, 0.0, 0.0, 0.0)
ON_ITS_SIDE = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)  # 90° about x


def watcher_spec(tmp_path: Path) -> SystemSpec:
    """The shipped specification with the walk-through's a_wt and its channels: WT_CHANNEL
    carries fipa-subscribe from a_wt to a_km as C7 carries it from a_hi (docs/spec.md)."""
    path = tmp_path / "spec.toml"
    path.write_text(staged(DEFAULT_SPEC.read_text(), snippet(1), entries(), edit=group_edit))
    return load(path)


class Subscriber:
    """Plays ``name``, subscribing to a_km's changes of the scene on ``channel``."""

    def __init__(self, bus: MemoryBus, channel: str, name: str) -> None:
        self.bus, self.channel, self.name = bus, channel, name
        self.inbox: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        bus.subscribe(keys.fipa_key(channel, "a_km", name), lambda _k, p: self.inbox.put(decode(p)))
        self.n = 0

    def send(self, performative: Performative, content: msgspec.Struct | bytes | None, cid: str) -> None:
        self.n += 1
        language: str | None = None
        encoding: str | None = None
        body = b""
        if isinstance(content, msgspec.Struct):
            (language, body), encoding = encode_content(content), "msgpack"
        elif content:
            language, body, encoding = "L_WM", content, "msgpack"
        msg = Communicate(
            performative=performative,
            sender=AgentIdentifier(self.name),
            receiver=(AgentIdentifier("a_km"),),
            content=body,
            language=language,
            encoding=encoding,
            ontology="O_RoCo" if body else None,
            protocol="fipa-subscribe",
            conversation_id=cid,
            reply_with=f"{cid}-{self.n}",
        )
        self.bus.publish(keys.fipa_key(self.channel, self.name, "a_km"), encode(msg))

    def subscribe(self, sub: msgspec.Struct | bytes, cid: str) -> tuple[Performative, object]:
        """Subscribe in conversation ``cid``; a_km's answer (its performative and content)."""
        self.send(Performative.SUBSCRIBE, sub, cid)
        return self.next()

    def next(self) -> tuple[Performative, object]:
        msg = self.inbox.get(timeout=TIMEOUT_S)
        if msg.language is not None and msg.encoding == "msgpack":
            return msg.performative, decode_content(msg.language, msg.content)
        return msg.performative, msg.content.decode()

    def change(self) -> SceneChange:
        performative, content = self.next()
        assert performative is Performative.INFORM and isinstance(content, SceneChange), content
        return content

    def nothing(self) -> bool:
        return self.inbox.empty()


@contextmanager
def running_km(
    spec: SystemSpec, monkeypatch: pytest.MonkeyPatch, bus: MemoryBus | None = None
) -> Iterator[tuple[KnowledgeManager, MemoryBus]]:
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    bus = bus or MemoryBus()
    km = KnowledgeManager(bus.transport(), spec)
    km.engine.bind()
    thread = threading.Thread(target=km.engine.run, name="a_km", daemon=True)
    thread.start()
    try:
        yield km, bus
    finally:
        km.engine.stop()
        thread.join(timeout=TIMEOUT_S)
        assert not thread.is_alive()
        km.close()


def seen(stamp: float, *objects: ObjectUpdate) -> WorldUpdate:
    """An observation of ``objects`` at robot time ``stamp``, received by a_ta at 1000 + stamp."""
    return WorldUpdate(stamp=stamp, objects=objects, seen_at=1000.0 + stamp)


def at(name: str, x: float, orientation: tuple[float, float, float, float] = UPRIGHT) -> ObjectUpdate:
    return ObjectUpdate(name=name, pose=Pose((x, 0.2, 0.9), orientation))


def settled(peer: Peer) -> None:
    """Return once a_km saved every update sent before (its informs went out before this)."""
    peer.object("jar")


@pytest.mark.walkthrough
def test_a_subscriber_is_told_when_an_object_moves_or_tilts_and_not_otherwise(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        peer, wt = Peer(bus), Subscriber(bus, WT_CHANNEL, "a_wt")
        peer.update(seen(1.0, at("jar", 0.80), at("bowl", 0.50)))
        settled(peer)
        performative, _ = wt.subscribe(SceneSubscription(objects=("jar",), moved=0.05, tilted=0.5), "w1")
        assert performative is Performative.AGREE
        # below the threshold, an object not of interest, and the same pose again: nothing
        peer.update(seen(2.0, at("jar", 0.83), at("bowl", 0.90)))
        peer.update(seen(3.0, at("jar", 0.83), at("bowl", 0.30)))
        settled(peer)
        assert wt.nothing()
        # the drift adds up: 6 cm from what was told, though 3 cm from the last observation
        peer.update(seen(4.0, at("jar", 0.86)))
        moved = wt.change()
        assert moved.object == "jar" and moved.changed == ("moved",)
        assert moved.distance == pytest.approx(0.06) and moved.stamp == 4.0 and moved.seen_at == 1004.0
        assert moved.pose == Pose((0.86, 0.2, 0.9)) and moved.tilt == 0.0
        # knocked over where it stands: its up axis 90° from upright
        peer.update(seen(5.0, at("jar", 0.86, ON_ITS_SIDE)))
        tilted = wt.change()
        assert tilted.changed == ("tilted",) and tilted.tilt == pytest.approx(math.pi / 2)
        assert tilted.stamp == 5.0
        # stood up again; then taken by a hand (an asserted change: no observation time)
        peer.update(seen(6.0, at("jar", 0.86)))
        assert wt.change().changed == ("upright",)
        peer.update(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", held_by="right_gripper"),)))
        held = wt.change()
        assert held.changed == ("held",) and held.held_by == "right_gripper" and held.seen_at is None
        # put on the table; then some of its content poured out
        put = ObjectUpdate(name="jar", held_by="", location="table", relation="on")
        peer.update(WorldUpdate(stamp=-1.0, objects=(put,)))
        placed = wt.change()
        assert placed.changed == ("released", "placed")
        assert (placed.location, placed.relation) == ("table", "on")
        peer.update(seen(7.0, ObjectUpdate(name="jar", particles=37)))
        poured = wt.change()
        assert poured.changed == ("content",) and poured.particles == 37 and poured.stamp == 7.0
        settled(peer)
        assert wt.nothing()
        assert km.counters["scene_changes"] == 6


@pytest.mark.walkthrough
def test_a_malformed_or_out_of_range_subscription_is_refused_with_the_reason(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        wt = Subscriber(bus, WT_CHANNEL, "a_wt")
        refused = [
            (SceneSubscription(moved=0.0), "moved must be 0.001..10.0 m, not 0.0"),
            (SceneSubscription(moved=50.0), "moved must be"),
            (SceneSubscription(tilted=4.0), "tilted must be"),
            (SceneSubscription(queue=0), "queue must be 1..256 changes, not 0"),
            (SceneSubscription(queue=100_000), "queue must be"),
            (SceneSubscription(objects=("jar", "no such jar")), "not an individual's name: 'no such jar'"),
            (SceneSubscription(objects=tuple(f"o{i}" for i in range(65))), "at most 64 objects"),
            (
                SceneSubscription(moved=None, tilted=None, content=False, relation=False),
                "no change is of interest",
            ),
        ]
        for n, (sub, reason) in enumerate(refused):
            performative, content = wt.subscribe(sub, f"bad{n}")
            assert performative is Performative.REFUSE and isinstance(content, str), sub
            assert reason in content, content
        # not a term a_km's role takes (the specification lists SceneSubscription only), and
        # bytes that are no term: not-understood from the runtime
        odd: tuple[msgspec.Struct | bytes, ...] = (Subscription("environment"), b"\x93no term")
        for n, term in enumerate(odd):
            performative, _ = wt.subscribe(term, f"odd{n}")
            assert performative is Performative.NOT_UNDERSTOOD
        assert not km.watches
        # a subscription in range is still agreed
        assert wt.subscribe(SceneSubscription(), "good")[0] is Performative.AGREE


@pytest.mark.walkthrough
def test_a_cancel_ends_the_informs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        peer, wt = Peer(bus), Subscriber(bus, WT_CHANNEL, "a_wt")
        peer.update(seen(1.0, at("jar", 0.80)))
        settled(peer)
        assert wt.subscribe(SceneSubscription(), "w1")[0] is Performative.AGREE
        peer.update(seen(2.0, at("jar", 0.70)))
        assert wt.change().changed == ("moved",)
        wt.send(Performative.CANCEL, SceneSubscription(), "w1")
        assert wt.next()[0] is Performative.INFORM  # the cancel answered (FIPA SC00026 §2)
        peer.update(seen(3.0, at("jar", 0.50)))
        settled(peer)
        assert wt.nothing()
        assert not km.watches and km.counters["scene_changes"] == 1


@pytest.mark.walkthrough
def test_the_queue_drops_the_oldest_and_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A planted flood: one update moves eight objects for a subscriber that keeps two."""
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        peer, wt = Peer(bus), Subscriber(bus, WT_CHANNEL, "a_wt")
        names = [f"thing{i}" for i in range(8)]
        peer.update(seen(1.0, *(at(name, 0.1 * i) for i, name in enumerate(names))))
        settled(peer)
        assert wt.subscribe(SceneSubscription(queue=2), "w1")[0] is Performative.AGREE
        peer.update(seen(2.0, *(at(name, 0.1 * i + 0.5) for i, name in enumerate(names))))
        first, second = wt.change(), wt.change()
        settled(peer)
        assert wt.nothing()
        assert (first.object, first.dropped) == ("thing6", 6)
        assert (second.object, second.dropped) == ("thing7", 0)
        assert km.counters["scene_changes_dropped"] == 6


@pytest.mark.walkthrough
def test_a_flood_larger_than_a_burst_arrives_whole_and_in_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        peer, wt = Peer(bus), Subscriber(bus, WT_CHANNEL, "a_wt")
        names = [f"thing{i}" for i in range(2 * scene_watch.BURST + 3)]
        peer.update(seen(1.0, *(at(name, 0.01 * i) for i, name in enumerate(names))))
        settled(peer)
        assert wt.subscribe(SceneSubscription(queue=64), "w1")[0] is Performative.AGREE
        peer.update(seen(2.0, *(at(name, 0.01 * i + 0.5) for i, name in enumerate(names))))
        assert [wt.change().object for _ in names] == sorted(names)
        assert km.counters["scene_changes_dropped"] == 0


@pytest.mark.walkthrough
def test_at_most_n_subscribers_and_one_per_channel(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(scene_watch, "MAX_SUBSCRIBERS", 1)
    with running_km(watcher_spec(tmp_path), monkeypatch) as (km, bus):
        hi, wt = Subscriber(bus, "C7", "a_hi"), Subscriber(bus, WT_CHANNEL, "a_wt")
        assert hi.subscribe(SceneSubscription(), "h1")[0] is Performative.AGREE
        performative, reason = wt.subscribe(SceneSubscription(), "w1")
        assert performative is Performative.REFUSE
        assert reason == "a_km serves at most 1 scene subscriptions at once"
        # a subscription again on the same channel replaces the earlier one
        assert hi.subscribe(SceneSubscription(objects=("jar",)), "h2")[0] is Performative.AGREE
        assert km.watches["C7"].conversation_id == "h2"
        hi.send(Performative.CANCEL, SceneSubscription(), "h2")
        assert hi.next()[0] is Performative.INFORM
        assert wt.subscribe(SceneSubscription(), "w2")[0] is Performative.AGREE
        assert list(km.watches) == [WT_CHANNEL]


@pytest.mark.walkthrough
def test_a_restarted_km_serves_the_subscription_the_subscriber_makes_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """a_km keeps no scene subscription across a restart: the subscriber's role subscribes
    again (a new attempt) when a_km's token reappears, and the changes go on."""
    spec = watcher_spec(tmp_path)
    bus = MemoryBus()
    watcher = Watcher(bus.transport(), spec)
    watcher.engine.bind()
    thread = threading.Thread(target=watcher.engine.run, name="a_wt", daemon=True)
    thread.start()
    try:
        for stamp, attempt in ((1.0, "wt-scene"), (10.0, "wt-scene-2")):  # a_km, then restarted
            with running_km(spec, monkeypatch, bus) as (km, _):
                assert watcher.agreed.get(timeout=TIMEOUT_S) == attempt
                peer = Peer(bus)
                peer.update(seen(stamp, at("jar", 0.80)))
                peer.update(seen(stamp + 1.0, at("jar", 0.60)))
                change = watcher.changes.get(timeout=TIMEOUT_S)
                assert change.object == "jar" and change.changed == ("moved",) and change.stamp == stamp + 1.0
                assert list(km.watches) == [WT_CHANNEL]
            km.engine.transport.close()  # its liveliness token goes, as when its process ends
    finally:
        watcher.engine.stop()
        thread.join(timeout=TIMEOUT_S)
