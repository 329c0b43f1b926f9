"""A replayed communicate beside the recorded one (services/replay/compare.py), and the sources
a replayed agent runs on (services/runtime/sources.py, services/replay/sources.py)."""

from __future__ import annotations

import msgspec

from services.agents.planner.agent import Planner
from services.replay.compare import TIME_TOLERANCE_S, IdMap, clock_fields, compare
from services.replay.record import Recorded
from services.replay.sources import ReplaySources
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.runtime.sources import SYSTEM
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.aid import aid
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_hc import Status, TaskStatus
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan, PlanNode

T0 = 1_800_000_000.0
KEY = keys.fipa_key("C3", "a_pl", "a_co")


def _plan(cost: float = 12.5, planning_time_s: float = 0.08) -> HierarchicalPlan:
    return HierarchicalPlan(
        plan_id="c-1-p1",
        task_id="c-1",
        root=PlanNode(name="pour(jar,bowl)"),
        cost=cost,
        planning_time_s=planning_time_s,
    )


def _inform(content: msgspec.Struct | None = None, reason: str = "", **ids: object) -> Communicate:
    language, body = encode_content(content) if content is not None else (None, reason.encode())
    fields: dict[str, object] = {"conversation_id": "c-1-plan1", "in_reply_to": "a_co-1", "reply_with": None}
    fields.update(ids)
    return Communicate(
        performative=Performative.INFORM if content is not None else Performative.FAILURE,
        sender=aid("a_pl"),
        receiver=(aid("a_co"),),
        content=body,
        language=language,
        encoding="msgpack" if content is not None else "utf-8",
        ontology="O_RoCo" if content is not None else None,
        protocol="fipa-request",
        **fields,  # type: ignore[arg-type]
    )


def _recorded(comm: Communicate, sent: float = T0 + 5.0) -> Recorded:
    return Recorded(seq=7, t=sent + 0.001, sent=sent, key=KEY, comm=comm)


def test_identifiers_pair_one_to_one() -> None:
    ids = IdMap()
    assert ids.pair("a_pl-rec1", "a_pl-rep1") is None
    assert ids.pair("a_pl-rec1", "a_pl-rep1") is None  # the same pair again
    assert ids.pair("a_pl-rec1", "a_pl-rep2") == "a_pl-rep2 (where a_pl-rec1 was replayed as a_pl-rep1)"
    assert ids.pair("a_pl-rec2", "a_pl-rep1") == "a_pl-rep1 (which stands for a_pl-rec1)"
    assert ids.replayed("a_pl-rec1") == "a_pl-rep1" and ids.replayed("a_co-1") == "a_co-1"


def test_a_field_read_from_a_clock_is_not_compared_and_the_others_are() -> None:
    assert clock_fields(HierarchicalPlan) == {"planning_time_s"}
    assert clock_fields(TaskStatus) == {"deadline_in_s"} and clock_fields(Status) == frozenset()
    recorded = _recorded(_inform(_plan(planning_time_s=0.081)))
    assert compare(recorded, _inform(_plan(planning_time_s=0.013)), T0 + 5.0, IdMap(), T0) == []
    (d,) = compare(recorded, _inform(_plan(cost=13.5)), T0 + 5.0, IdMap(), T0)
    assert (d.seq, d.field, d.recorded, d.replayed) == (7, "content.cost", "12.5", "13.5")
    assert (
        d.line()
        == "#7 at   5.001 s a_pl → a_co inform (fipa-request): content.cost: recorded 12.5, replayed 13.5"
    )


def test_reply_by_is_compared_as_the_time_it_leaves_after_sending() -> None:
    recorded = _recorded(_inform(_plan(), reply_by=T0 + 5.0 + 30.0))
    near = T0 + 4.9 + 30.0 + TIME_TOLERANCE_S / 2  # the replay's clock stood at 4.9 s
    assert compare(recorded, _inform(_plan(), reply_by=near), T0 + 4.9, IdMap(), T0) == []
    (d,) = compare(recorded, _inform(_plan(), reply_by=T0 + 4.9 + 10.0), T0 + 4.9, IdMap(), T0)
    assert (d.field, d.recorded, d.replayed) == (
        "reply-by",
        "30.000 s after sending",
        "10.000 s after sending",
    )
    (d,) = compare(recorded, _inform(_plan()), T0 + 4.9, IdMap(), T0)
    assert (d.field, d.replayed) == ("reply-by", "(none)")


def test_a_reason_in_words_is_compared_with_its_identifiers_renamed() -> None:
    ids = IdMap()
    ids.pair("c-recorded", "c-replayed")
    said = "no answer in conversation {} by its reply-by"
    recorded = _recorded(_inform(reason=said.format("c-recorded")))
    assert compare(recorded, _inform(reason=said.format("c-replayed")), T0, ids, T0) == []
    (d,) = compare(recorded, _inform(reason=said.format("c-other")), T0, ids, T0)
    assert d.field == "content" and "c-other" in d.replayed


def test_replay_sources_move_only_forward_and_draw_the_same_ids_for_a_seed() -> None:
    s = ReplaySources(T0)
    s.set(T0 + 2.0)
    s.set(T0 + 1.0)
    assert s.time() == s.monotonic() == T0 + 2.0
    assert (
        s.new_id("a_pl-") == ReplaySources(0.0).new_id("a_pl-") != ReplaySources(0.0, seed=1).new_id("a_pl-")
    )


class _Offering:
    """A transport offering sources (services/runtime/transport.py ``Transport``)."""

    def __init__(self, bus: MemoryBus, sources: ReplaySources) -> None:
        self.inner = bus.transport()
        self.sources = sources
        self.publish, self.subscribe = self.inner.publish, self.inner.subscribe
        self.announce, self.watch, self.close = self.inner.announce, self.inner.watch, self.inner.close


def test_an_agent_takes_its_transport_s_sources_or_the_system_s() -> None:
    bus = MemoryBus()
    assert Planner(bus.transport()).sources is SYSTEM
    sources = ReplaySources(T0 + 100.0)
    agent = Planner(_Offering(bus, sources))  # type: ignore[arg-type]
    assert agent.sources is sources
    expected = ReplaySources(T0 + 100.0)
    sent = agent.engine.send("a_km", Performative.QUERY_REF, None, protocol="fipa-query", reply_by_s=30.0)
    assert sent.reply_by == T0 + 130.0  # the deadline from the replay's clock
    assert sent.reply_with == expected.new_id("a_pl-") and sent.conversation_id == expected.new_id("c-")
