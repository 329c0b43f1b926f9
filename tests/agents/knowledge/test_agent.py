"""a_km as an agent (services/agents/knowledge/agent.py) on a MemoryBus: its knowledge survives a
restart on the same store, and queries it cannot answer get refuse/failure with a reason while
it keeps running."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import msgspec
import pytest

from services.agents.knowledge import agent as km_agent
from services.agents.knowledge.agent import KnowledgeManager, store_path
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import (
    Answer,
    HypotheticalQuery,
    ObjectInfo,
    ObjectQuery,
    ObjectUpdate,
    PourStep,
    SparqlQuery,
    Subscription,
    WorldUpdate,
)

TIMEOUT_S = 10.0


class Peer:
    """Plays a_pl (queries on C4) and a_ta (updates on C6) towards one a_km on a bus."""

    def __init__(self, bus: MemoryBus) -> None:
        self.bus = bus
        self.replies: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        bus.subscribe(keys.fipa_key("C4", "a_km", "a_pl"), lambda _k, p: self.replies.put(decode(p)))
        self.subscribes: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        bus.subscribe(keys.fipa_key("C6", "a_km", "a_ta"), lambda _k, p: self.subscribes.put(decode(p)))
        self.agreed = False
        self.environment = ""
        """The conversation-id of a_km's environment subscription agreed to."""
        self.n = 0

    def _send(self, channel: str, sender: str, msg: Communicate) -> None:
        self.bus.publish(keys.fipa_key(channel, sender, "a_km"), encode(msg))

    def query(
        self, content: msgspec.Struct | None, performative: Performative = Performative.QUERY_REF
    ) -> tuple[Communicate, msgspec.Struct | str | None]:
        """Send a query as a_pl; return a_km's reply and its decoded content (a reason as str)."""
        return self.answer(self.ask(content, performative))

    def ask(self, content: msgspec.Struct | None, performative: Performative = Performative.QUERY_REF) -> str:
        """Send a query as a_pl without waiting; returns its reply-with."""
        self.n += 1
        language, body = encode_content(content) if content is not None else (None, b"")
        msg = Communicate(
            performative=performative,
            sender=AgentIdentifier("a_pl"),
            receiver=(AgentIdentifier("a_km"),),
            content=body,
            language=language,
            encoding="msgpack" if body else None,
            ontology="O_RoCo" if body else None,
            protocol="fipa-query",
            conversation_id=f"q{self.n}",
            reply_with=f"q{self.n}",
        )
        self._send("C4", "a_pl", msg)
        return f"q{self.n}"

    def answer(self, reply_with: str) -> tuple[Communicate, msgspec.Struct | str | None]:
        """a_km's next reply on C4, which must answer ``reply_with``, and its decoded content."""
        reply = self.replies.get(timeout=TIMEOUT_S)
        assert reply.in_reply_to == reply_with
        if reply.language is not None:
            return reply, decode_content(reply.language, reply.content)
        return reply, reply.content.decode() or None

    def update(self, update: WorldUpdate) -> None:
        """Send an observation or asserted change as a_ta (in the subscription a_km opened,
        agreed to first, as fipa-subscribe has it)."""
        if not self.agreed:
            subscribe = self.subscribes.get(timeout=TIMEOUT_S)
            while not self.subscribes.empty():  # a_km asked again meanwhile: answer its latest
                subscribe = self.subscribes.get_nowait()
            self._send("C6", "a_ta", subscribe.reply(Performative.AGREE, sender=AgentIdentifier("a_ta")))
            self.agreed = True
            self.environment = subscribe.conversation_id or ""  # each attempt has an id of its own
        language, body = encode_content(update)
        self._send(
            "C6",
            "a_ta",
            Communicate(
                performative=Performative.INFORM,
                sender=AgentIdentifier("a_ta"),
                receiver=(AgentIdentifier("a_km"),),
                content=body,
                language=language,
                encoding="msgpack",
                ontology="O_RoCo",
                protocol="fipa-subscribe",
                conversation_id=self.environment,
            ),
        )

    def object(self, name: str) -> ObjectInfo:
        reply, content = self.query(ObjectQuery(name))
        assert reply.performative is Performative.INFORM_REF and isinstance(content, Answer)
        return content.objects[0]


@contextmanager
def running_km() -> Iterator[tuple[KnowledgeManager, Peer]]:
    bus = MemoryBus()
    peer = Peer(bus)
    km = KnowledgeManager(bus.transport())
    km.engine.bind()
    thread = threading.Thread(target=km.engine.run, name="a_km", daemon=True)
    thread.start()
    try:
        yield km, peer
    finally:
        km.engine.stop()
        thread.join(timeout=TIMEOUT_S)
        assert not thread.is_alive()
        km.close()  # what services.runtime.main does after run() ends


def test_store_path_comes_from_the_environment(tmp_path: Path) -> None:
    assert store_path({"ROCO_KM_STORE": str(tmp_path / "a"), "ROCO_RUN_DIR": str(tmp_path)}) == tmp_path / "a"
    assert store_path({"ROCO_RUN_DIR": str(tmp_path)}) == tmp_path / "km_store"
    assert store_path({"ROCO_KM_STORE": "", "ROCO_RUN_DIR": ""}) is None
    assert store_path({}) is None


@pytest.mark.requirement("R2.4")
def test_a_restarted_km_answers_with_the_knowledge_the_first_saved(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROCO_KM_STORE", str(tmp_path / "km"))
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    with running_km() as (km, peer):
        assert km.world.path == tmp_path / "km" and not km.world.kept
        peer.update(WorldUpdate(stamp=3.0, objects=(ObjectUpdate(name="jar", pose=Pose((0.8, 0.22, 0.9))),)))
        peer.update(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="bowl", held_by="right_gripper"),)))
        # a_km takes its inputs in order: the answer comes after both updates were saved
        assert peer.object("bowl").held_by == "right_gripper"
        assert km.counters["updates"] == 2
    monkeypatch.setattr(km_agent, "HOLD_QUERIES_S", 0.0)  # answer from the kept knowledge at once
    with running_km() as (km, peer):
        assert km.world.kept
        jar = peer.object("jar")
        assert jar.pose == Pose((0.8, 0.22, 0.9)) and jar.pose_stamp == 3.0
        bowl = peer.object("bowl")
        assert bowl.held_by == "right_gripper" and bowl.picked_from == "cabinet"


@pytest.mark.requirement("R2.4")
def test_unanswerable_queries_get_a_reason_and_km_keeps_running(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    with running_km() as (km, peer):
        assert km.world.path is None
        cases = [
            (ObjectQuery("teapot"), Performative.FAILURE, "teapot"),
            (SparqlQuery("SELECT WHERE {"), Performative.FAILURE, "bad SPARQL"),
            (SparqlQuery("DESCRIBE roco:jar"), Performative.REFUSE, "SELECT and ASK"),
            (Subscription("environment"), Performative.NOT_UNDERSTOOD, "not Subscription"),  # spec: contents
            (None, Performative.REFUSE, "no content"),
        ]
        for query, performative, reason in cases:
            reply, content = peer.query(query)
            assert reply.performative is performative, query
            assert isinstance(content, str) and reason in content
        # still answering, hypothetical queries included (through questionAnswering)
        reply, content = peer.query(
            HypotheticalQuery(
                changes=(ObjectUpdate(name="jar", held_by="left_gripper"),),
                query=SparqlQuery("ASK { roco:jar roco:heldBy roco:left_gripper }"),
            )
        )
        assert reply.performative is Performative.INFORM_REF
        assert isinstance(content, Answer) and content.boolean is True
        reply, content = peer.query(SparqlQuery("ASK { roco:jar roco:heldBy ?g }"), Performative.QUERY_IF)
        assert reply.performative is Performative.INFORM
        assert isinstance(content, Answer) and content.boolean is False
        assert km.counters["behaviour_errors"] == 0


def kept_jar_seen_at_3s(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A first a_km run on the store ``tmp_path/km`` that saved the jar observed at t = 3 s."""
    monkeypatch.setenv("ROCO_KM_STORE", str(tmp_path / "km"))
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    with running_km() as (_km, peer):
        peer.update(WorldUpdate(stamp=3.0, objects=(ObjectUpdate(name="jar", pose=Pose((0.8, 0.22, 0.9))),)))
        assert peer.object("jar").pose_stamp == 3.0


def test_a_restarted_km_holds_queries_until_a_tas_first_observation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Kept knowledge may be a step behind (an update in flight when a_km stopped is lost):
    a query that arrives before a_ta's first observation is answered after it, from it."""
    kept_jar_seen_at_3s(tmp_path, monkeypatch)
    with running_km() as (km, peer):
        assert km.world.kept
        asked = peer.ask(ObjectQuery("jar"))  # before the observation: a_km takes it first
        peer.update(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", held_by="right_gripper"),)))
        peer.update(WorldUpdate(stamp=5.0, objects=(ObjectUpdate(name="jar", pose=Pose((0.6, 0.1, 1.1))),)))
        reply, content = peer.answer(asked)
        assert reply.performative is Performative.INFORM_REF and isinstance(content, Answer)
        (jar,) = content.objects
        assert jar.pose_stamp == 5.0 and jar.pose == Pose((0.6, 0.1, 1.1))
        assert jar.held_by == "right_gripper"
        # once the observation is in, queries are answered at once again
        assert peer.object("jar").pose_stamp == 5.0 and not km.held


def test_a_restarted_km_answers_held_queries_when_no_observation_comes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The hold is bounded: with a_ta silent, the query is answered from the kept knowledge."""
    kept_jar_seen_at_3s(tmp_path, monkeypatch)
    monkeypatch.setattr(km_agent, "HOLD_QUERIES_S", 0.5)
    with running_km() as (km, peer):
        asked = peer.ask(ObjectQuery("jar"))
        reply, content = peer.answer(asked)
        assert reply.performative is Performative.INFORM_REF and isinstance(content, Answer)
        assert content.objects[0].pose_stamp == 3.0
        assert km.hold_until is None and not km.held


@pytest.mark.requirement("R2.3")
def test_a_plan_whose_step_cannot_run_is_answered_failure_with_the_step_and_the_reason(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """FIPA query (SC00027): a_km tried the query and could not answer it: ``failure``."""
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    goal = SparqlQuery("ASK { roco:bowl roco:particles ?n . FILTER(?n >= 84) }")
    pour = PourStep(index=7, source="jar", target="bowl")
    with running_km() as (_km, peer):
        peer.update(
            WorldUpdate(
                stamp=1.0,
                objects=(
                    ObjectUpdate(name="jar", held_by="left_gripper", particles=20),
                    ObjectUpdate(name="bowl", particles=70),
                ),
            )
        )
        reply, content = peer.query(HypotheticalQuery(steps=(pour,), query=goal))
        assert reply.performative is Performative.FAILURE
        assert content == (
            "step 7 pour(jar, bowl): the bowl cannot take what the jar holds: "
            "20 particles into 70, capacity 84"
        )
        # the same plan with room in the bowl reaches its goal
        peer.update(WorldUpdate(stamp=2.0, objects=(ObjectUpdate(name="bowl", particles=64),)))
        reply, content = peer.query(HypotheticalQuery(steps=(pour,), query=goal))
        assert reply.performative is Performative.INFORM_REF
        assert isinstance(content, Answer) and content.boolean is True
        assert peer.object("bowl").particles == 64  # the real state is untouched


def test_an_update_that_renews_the_world_replaces_what_km_believed(monkeypatch: pytest.MonkeyPatch) -> None:
    """a_ta's update for a power-cycled robot (``renews``): a_km drops the jar it believed held
    and seen at 268 s, and answers from the initial kitchen with the new observation (t = 0.9 s),
    which it would have ignored as stale otherwise."""
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    with running_km() as (km, peer):
        peer.update(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", held_by="right_gripper"),)))
        peer.update(WorldUpdate(stamp=268.2, objects=(ObjectUpdate(name="jar", pose=Pose((0.6, 0.1, 1.1))),)))
        assert peer.object("jar").held_by == "right_gripper"
        fresh = Pose((0.8, 0.22, 0.9))
        peer.update(WorldUpdate(stamp=0.9, objects=(ObjectUpdate(name="jar", pose=fresh),), renews=True))
        jar = peer.object("jar")
        assert not jar.held_by and jar.location == "cabinet"
        assert jar.pose == fresh and jar.pose_stamp == 0.9
        assert km.counters["renewals"] == 1 and km.world.stale_poses == 0
