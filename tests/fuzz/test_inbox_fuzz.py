"""Every agent's inbox fuzzed: each of the six agents, built as in the
fleet, takes in malformed communicates through its runtime (the transport callback, then the
elementary action's acquire and dispatch) and must answer every one it can with
not-understood, count it under its reason, act on none, and go on serving."""

from __future__ import annotations

import queue
import random
import threading
from typing import Any

import msgspec
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from services.agents.coordinator.agent import Coordinator
from services.agents.executor.agent import ExecutorAgent
from services.agents.human_interface.agent import HumanInterface
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.planner.agent import Planner
from services.agents.task_executor.agent import TaskExecutor
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.counters import CountersReport
from services.runtime.limits import REJECT_REASONS
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery
from tests.fuzz.strategies import AGENTS, Fuzz, flood, malformed, oversized
from tests.support.fake_executor import FakeExecutor
from tests.support.memory_fleet import MemoryFleet
from tests.support.messages import communicate


class _Executor(ExecutorAgent):
    def make_executor(self) -> Any:
        return FakeExecutor()


CLASSES: dict[str, type[Agent]] = {
    "a_hi": HumanInterface,
    "a_co": Coordinator,
    "a_pl": Planner,
    "a_km": KnowledgeManager,
    "a_ta": TaskExecutor,
    "ag_ex": _Executor,
}


class Inbox:
    """One agent on its own MemoryBus, stepped by hand: :meth:`feed` puts a payload on a key
    and runs the runtime's acquire and dispatch; returns what the agent published."""

    def __init__(self, name: str) -> None:
        self.bus = MemoryBus()
        self.agent = CLASSES[name](self.bus.transport())
        self.agent.engine.bind()
        self.out: list[tuple[str, bytes]] = []
        self.bus.subscribe(f"roco/fipa/*/{name}/*", lambda k, p: self.out.append((k, p)))
        self.seen: set[bytes] = set()

    def feed(self, key: str, payload: bytes) -> list[tuple[str, Communicate]]:
        self.out.clear()
        self.bus.publish(key, payload)
        self.agent.engine.acquire()
        self.agent.engine.dispatch()
        return [(k, decode(p)) for k, p in self.out]


_inboxes: dict[str, Inbox] = {}


def inbox(name: str) -> Inbox:
    if name not in _inboxes:
        _inboxes[name] = Inbox(name)
    return _inboxes[name]


def check_rejected(box: Inbox, f: Fuzz) -> None:
    """``f`` is answered with one not-understood (or, when it is a byte-identical copy of an
    earlier one, dropped as a duplicate), counted under its reason, and not acted on."""
    agent = box.agent
    before = dict(agent.counters)
    copy = f.payload in box.seen
    box.seen.add(f.payload)
    out = box.feed(f.key, f.payload)
    assert not agent.engine.x, f"{f.kind} reached the agent: {agent.engine.x[0].msg}"
    if copy:
        assert out == [] and agent.counters["duplicates"] == before.get("duplicates", 0) + 1
        return
    channel = keys.parse_fipa_key(f.key).channel
    assert len(out) == 1, (f.kind, out)
    key, nu = out[0]
    assert key == keys.fipa_key(channel, agent.name, f.sender)
    assert nu.performative is Performative.NOT_UNDERSTOOD and nu.conversation_id == f.cid
    assert nu.content and nu.encoding == "utf-8"  # the reason, readable
    reason = f"rejected.{f.reason}"
    assert agent.counters[reason] == before.get(reason, 0) + 1, (f.kind, nu.content)
    assert agent.counters["rejected"] == before.get("rejected", 0) + 1


@pytest.mark.parametrize("name", AGENTS)
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_every_malformed_communicate_is_answered_counted_and_not_acted_on(
    name: str, data: st.DataObject
) -> None:
    box = inbox(name)
    check_rejected(box, data.draw(malformed(name)))


@pytest.mark.parametrize("name", AGENTS)
def test_oversized_communicates_are_rejected_as_such(name: str) -> None:
    box = Inbox(name)
    check_rejected(box, oversized(name))
    assert box.agent.counters["rejected.malformed"] == 0


def test_reasons_counted_are_documented() -> None:
    for box in _inboxes.values():
        for counter in box.agent.counters:
            if counter.startswith("rejected."):
                assert counter.split(".", 1)[1] in REJECT_REASONS


def test_a_knowledge_manager_flooded_with_bad_input_still_accepts_a_valid_query() -> None:
    box = Inbox("a_km")
    rng = random.Random(8)
    for _ in range(500):
        box.feed(keys.fipa_key("C4", "a_pl", "a_km"), rng.randbytes(rng.randrange(64)))
    q = communicate(
        Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", "c-valid", ObjectQuery("jar"), reply_with="q1"
    )
    assert box.feed(keys.fipa_key("C4", "a_pl", "a_km"), encode(q)) == []
    assert len(box.agent.engine.x) == 1 and box.agent.engine.x[0].msg.reply_with == "q1"


def test_new_conversations_beyond_the_bound_per_peer_are_refused() -> None:
    box = Inbox("a_km")
    box.agent.engine.max_open_per_peer = 3
    key = keys.fipa_key("C4", "a_pl", "a_km")
    for i in range(3):  # a_km does not answer here: three query conversations stay open
        q = communicate(
            Performative.QUERY_REF,
            "a_pl",
            "a_km",
            "fipa-query",
            f"c{i}",
            ObjectQuery("jar"),
            reply_with=f"q{i}",
        )
        assert box.feed(key, encode(q)) == []
    assert box.agent.engine.protocol_states.open_with("a_pl") == 3
    q = communicate(
        Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", "c3", ObjectQuery("jar"), reply_with="q3"
    )
    ((_, answer),) = box.feed(key, encode(q))
    assert answer.performative is Performative.REFUSE and answer.in_reply_to == "q3"
    assert b"at most 3" in answer.content
    assert box.agent.counters["rejected.too_many_conversations"] == 1
    assert len(box.agent.engine.x) == 3  # the refused one never reached the agent
    assert box.agent.engine.protocol_states.open_with("a_pl") == 3  # and its conversation ended
    # another peer is not affected, and an answer in an open conversation still goes through
    box.agent.engine.x.clear()
    box.agent.engine.reply(_received(box, "c0"), Performative.INFORM_REF, Answer())
    box.agent.engine.dispatch()
    assert box.agent.engine.protocol_states.open_with("a_pl") == 2
    q = communicate(
        Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", "c4", ObjectQuery("jar"), reply_with="q4"
    )
    assert box.feed(key, encode(q)) == [] and len(box.agent.engine.x) == 1


def _received(box: Inbox, cid: str) -> Any:
    from services.runtime.agent import Received

    q = communicate(
        Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", cid, ObjectQuery("jar"), reply_with="q0"
    )
    return Received.of(q, ObjectQuery("jar"), "C4")


def test_a_fleet_flooded_with_malformed_communicates_completes_a_pour_and_keeps_serving() -> None:
    """All six agents in their threads; 1500 malformed communicates to each while the pour
    runs; then the task has succeeded, every agent answers a counters request, the counts
    show the rejects, and a_km answers a query."""
    per_agent = 1500
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        stop = threading.Event()
        sent: dict[str, int] = dict.fromkeys(AGENTS, 0)

        def flood_all() -> None:
            rng = random.Random(3)
            for _ in range(per_agent):
                for a in AGENTS:
                    if stop.is_set():
                        return
                    f = flood(a, rng)
                    fleet.bus.publish(f.key, f.payload)
                    sent[a] += 1

        t = threading.Thread(target=flood_all, daemon=True)
        t.start()
        reports = fleet.command("pour the jar into the bowl", timeout=120)
        t.join(timeout=120)
        stop.set()
        assert reports[-1].kind.value == "succeeded", reports[-1]
        assert all(th.is_alive() for th in fleet.threads)
        got: queue.SimpleQueue[CountersReport] = queue.SimpleQueue()
        fleet.bus.subscribe(
            keys.COUNTERS_ALL, lambda k, p: got.put(msgspec.json.decode(p, type=CountersReport))
        )
        fleet.bus.publish(keys.COUNTERS_ASK, b"")
        answers: dict[str, dict[str, int]] = {}
        while len(answers) < len(AGENTS):
            report = got.get(timeout=30)
            answers[report.agent] = report.counters
        for a in AGENTS:
            rejects = sum(v for k, v in answers[a].items() if k.startswith("rejected."))
            assert rejects >= per_agent * 0.9, (a, answers[a])
            assert (
                answers[a].get("rejected.internal", 0) == 0 and answers[a].get("behaviour_errors", 0) == 0
            ), (a, answers[a])
        replies: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        fleet.bus.subscribe(keys.fipa_key("C4", "a_km", "a_pl"), lambda k, p: replies.put(decode(p)))
        q = communicate(
            Performative.QUERY_REF,
            "a_pl",
            "a_km",
            "fipa-query",
            "c-after",
            ObjectQuery("jar"),
            reply_with="q-after",
        )
        fleet.bus.publish(keys.fipa_key("C4", "a_pl", "a_km"), encode(q))
        while True:
            r = replies.get(timeout=10)
            if r.in_reply_to == "q-after":
                break
        assert r.performative is Performative.INFORM_REF


@pytest.mark.parametrize("name", AGENTS)
def test_every_communicate_of_the_flood_generator_is_rejected_for_its_reason(name: str) -> None:
    """The live fuzzer (test_live_fuzz.py) sends what :func:`flood` makes: each one must be
    answered and counted like the Hypothesis-drawn ones."""
    box = Inbox(name)
    rng = random.Random(name)
    for _ in range(300):
        check_rejected(box, flood(name, rng))
