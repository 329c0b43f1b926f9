"""The fault layer (services/runtime/faults.py) over the in-memory transport, seeded: each
message fault happens with its configured probability (bounds at about 3 σ), network faults
and partitions act as documented, clearing restores the fast path, every fault is an event,
and live control over the control keys reaches the transport."""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable, Iterator

import msgspec
import pytest

from services.runtime import keys
from services.runtime.faults import (
    CONTROL_ALL,
    EVENT_ALL,
    STATE_ALL,
    FaultEvent,
    FaultReport,
    FaultSettings,
    FaultUpdate,
    FaultyTransport,
    MessageFaults,
    NetFaults,
    control_key,
    parse_settings,
    settings_from_env,
)
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Performative, encode
from shared.fipa_codec.batch import pack
from tests.support.messages import communicate

KEY = keys.fipa_key("C4", "a_km", "a_pl")
N = 2000


class Sink:
    """Collects what arrives on a key expression of a bus; waits on conditions with deadlines."""

    def __init__(self, bus: MemoryBus, key_expr: str) -> None:
        self.items: list[tuple[str, bytes]] = []
        self._cond = threading.Condition()
        bus.subscribe(key_expr, self._on)

    def _on(self, key: str, payload: bytes) -> None:
        with self._cond:
            self.items.append((key, payload))
            self._cond.notify_all()

    def wait(self, pred: Callable[[list[tuple[str, bytes]]], bool], timeout: float = 10.0) -> None:
        with self._cond:
            if not self._cond.wait_for(lambda: pred(self.items), timeout):
                raise AssertionError(f"condition not met within {timeout} s ({len(self.items)} items)")

    @property
    def payloads(self) -> list[bytes]:
        with self._cond:
            return [p for _, p in self.items]


def events_of(sink: Sink) -> list[FaultEvent]:
    dec = msgspec.json.Decoder(FaultEvent)
    return [dec.decode(p) for p in sink.payloads]


def numbered(n: int = N) -> list[bytes]:
    """``n`` distinct payloads: the sequence number as 8 bytes (not communicates)."""
    return [i.to_bytes(8, "big") for i in range(n)]


@pytest.fixture
def bus() -> MemoryBus:
    return MemoryBus()


@pytest.fixture
def make(bus: MemoryBus) -> Iterator[Callable[..., FaultyTransport]]:
    made: list[FaultyTransport] = []

    def factory(settings: FaultSettings | None = None, agent: str = "a_km") -> FaultyTransport:
        t = FaultyTransport(bus.transport(), agent, settings)
        made.append(t)
        return t

    yield factory
    for t in made:
        t.close()


def channel(**faults: float) -> FaultSettings:
    return FaultSettings(seed=7, channels={"C4": MessageFaults(**faults)})


def within(count: int, p: float, n: int = N) -> bool:
    """``count`` successes of ``n`` Bernoulli(p) trials lies within 3.3 σ of n·p."""
    sigma = (n * p * (1 - p)) ** 0.5
    return abs(count - n * p) <= 3.3 * sigma


def test_no_fault_passes_everything_unchanged_on_the_fast_path(bus: MemoryBus, make: Callable) -> None:
    sink = Sink(bus, KEY)
    t = make()
    assert not t.active
    sent = numbered(100)
    for p in sent:
        t.publish(KEY, p)
    assert sink.payloads == sent  # synchronous: the memory bus delivers before publish returns


def test_drop_happens_with_its_probability(bus: MemoryBus, make: Callable) -> None:
    sink, events = Sink(bus, KEY), Sink(bus, EVENT_ALL)
    t = make(channel(drop=0.3))
    for p in numbered():
        t.publish(KEY, p)
    dropped = N - len(sink.payloads)
    assert within(dropped, 0.3), dropped
    assert sink.payloads == sorted(sink.payloads)  # order kept
    events.wait(lambda items: len(items) >= dropped + 1)  # + the settings event at start
    kinds = [e.kind for e in events_of(events)]
    assert kinds.count("drop") == dropped == t.applied["drop"]
    assert kinds[0] == "settings"


def test_duplicate_happens_with_its_probability(bus: MemoryBus, make: Callable) -> None:
    sink = Sink(bus, KEY)
    t = make(channel(duplicate=0.2))
    for p in numbered():
        t.publish(KEY, p)
    extra = len(sink.payloads) - N
    assert within(extra, 0.2), extra
    assert extra == t.applied["duplicate"]
    assert set(sink.payloads) == set(numbered())  # nothing lost, copies back to back
    assert sink.payloads == sorted(sink.payloads)


def test_a_batch_meets_its_faults_one_communicate_at_a_time(bus: MemoryBus, make: Callable) -> None:
    sink, events = Sink(bus, KEY), Sink(bus, EVENT_ALL)
    sent = [
        encode(communicate(Performative.INFORM, "a_km", "a_pl", "fipa-subscribe", f"c-{i}")) for i in range(3)
    ]
    make().publish(KEY, pack(sent))
    assert sink.payloads == sent  # no fault: the batch goes as it is (the bus delivers each)
    t = make(channel(duplicate=1.0))
    t.publish(KEY, pack(sent))
    assert sink.payloads[3:] == [sent[0], sent[0], sent[1], sent[1], sent[2], sent[2]]
    events.wait(lambda items: len(items) >= 4)  # the settings, then one per communicate
    copies = [e for e in events_of(events) if e.kind == "duplicate"]
    assert [e.conversation_id for e in copies] == ["c-0", "c-1", "c-2"]


def test_corrupt_happens_with_its_probability_and_alters_bytes(bus: MemoryBus, make: Callable) -> None:
    sink = Sink(bus, KEY)
    t = make(channel(corrupt=0.25))
    sent = numbered()
    for p in sent:
        t.publish(KEY, p)
    got = sink.payloads
    assert len(got) == N
    changed = sum(a != b for a, b in zip(sent, got, strict=True))
    assert within(changed, 0.25), changed
    assert changed == t.applied["corrupt"]
    assert all(len(a) == len(b) for a, b in zip(sent, got, strict=True))


def test_delay_happens_with_its_probability_and_off_the_caller_thread(bus: MemoryBus, make: Callable) -> None:
    """Each publication either arrives before ``publish`` returns (the memory bus delivers on the
    caller's thread) or is delayed: then it has not arrived when ``publish`` returns, and arrives
    later on another thread. ``publish`` never waits for a delay."""
    caller = threading.get_ident()
    on_thread: dict[bytes, int] = {}

    def on(_key: str, payload: bytes) -> None:
        on_thread.setdefault(payload, threading.get_ident())

    bus.subscribe(KEY, on)
    sink = Sink(bus, KEY)
    t = make(channel(delay=0.1, delay_s=0.5))
    sent = numbered()
    late = []
    for p in sent:
        t.publish(KEY, p)
        if p not in on_thread:  # publish returned before p arrived
            late.append(p)
    assert within(len(late), 0.1), len(late)
    assert len(late) == t.applied["delay"]  # every delayed one: publish did not wait for it
    sink.wait(lambda items: len(items) == N)  # the delayed ones arrive later
    assert {p for p, thread in on_thread.items() if thread != caller} == set(late)
    assert sorted(sink.payloads) == sent
    assert sink.payloads != sent  # the late ones are out of order


def test_delayed_communicates_are_late_by_the_delay(bus: MemoryBus, make: Callable) -> None:
    arrived: dict[bytes, float] = {}

    def on(_key: str, payload: bytes) -> None:
        arrived.setdefault(payload, time.monotonic())

    bus.subscribe(KEY, on)
    t = make(channel(delay=1.0, delay_s=0.15))
    t0 = time.monotonic()
    t.publish(KEY, b"late")
    assert b"late" not in arrived
    deadline = time.monotonic() + 5
    while b"late" not in arrived and time.monotonic() < deadline:
        t.flush()
    assert arrived[b"late"] - t0 >= 0.15


def test_reorder_swaps_a_communicate_with_the_next(bus: MemoryBus, make: Callable) -> None:
    sink = Sink(bus, KEY)
    t = make(channel(reorder=0.2, hold_s=5.0))
    sent = numbered()
    for p in sent:
        t.publish(KEY, p)
    held = t.applied["reorder"]
    # a held one cannot be held again, so ≈ N·p/(1+p) are held (one may still be held)
    assert within(held, 0.2 / 1.2), held
    sink.wait(lambda items: len(items) == N)  # the last one, if held, after hold_s at most
    got = [int.from_bytes(p, "big") for p in sink.payloads]
    assert sorted(got) == list(range(N))
    swaps = sum(1 for a, b in itertools.pairwise(got) if a > b)
    assert swaps == held


def test_reordered_communicate_is_released_after_hold_s_without_a_next(
    bus: MemoryBus, make: Callable
) -> None:
    sink = Sink(bus, KEY)
    t = make(channel(reorder=1.0, hold_s=0.1))
    t.publish(KEY, b"only")
    assert sink.payloads == []
    sink.wait(lambda items: len(items) == 1, timeout=5)


def test_same_seed_same_faults(bus: MemoryBus, make: Callable) -> None:
    runs = []
    for agent in ("a_km", "a_km"):
        other = MemoryBus()
        sink = Sink(other, KEY)
        t = FaultyTransport(other.transport(), agent, channel(drop=0.2, duplicate=0.2, corrupt=0.2))
        for p in numbered(500):
            t.publish(KEY, p)
        t.close()
        runs.append(sink.payloads)
    assert runs[0] == runs[1]


def test_channel_faults_touch_only_their_channel_and_star_covers_the_rest(
    bus: MemoryBus, make: Callable
) -> None:
    c4, c6, state = Sink(bus, KEY), Sink(bus, keys.fipa_key("C6", "a_km", "a_ta")), Sink(bus, "roco/state/*")
    t = make(FaultSettings(channels={"C6": MessageFaults(drop=1.0)}))
    for p in numbered(50):
        t.publish(KEY, p)
        t.publish(keys.fipa_key("C6", "a_km", "a_ta"), p)
        t.publish(keys.state_key("a_km"), p)
    assert len(c4.payloads) == 50 and len(c6.payloads) == 0 and len(state.payloads) == 50
    t.update(FaultUpdate(clear_channels=["C6"], set_channels={"*": MessageFaults(drop=1.0)}))
    t.publish(KEY, b"x")
    t.publish(keys.state_key("a_km"), b"x")  # not a communicate: no message faults
    assert len(c4.payloads) == 50 and len(state.payloads) == 51


def test_net_loss_and_delay_of_the_own_service_only(bus: MemoryBus, make: Callable) -> None:
    sink = Sink(bus, KEY)
    t = make(FaultSettings(seed=3, services={"a_km": NetFaults(loss=0.4), "a_pl": NetFaults(loss=1.0)}))
    for p in numbered():
        t.publish(KEY, p)
    lost = N - len(sink.payloads)
    assert within(lost, 0.4), lost
    assert t.applied["net_loss"] == lost
    t.update(FaultUpdate(set_services={"a_km": NetFaults(delay_s=0.1)}))
    before = len(sink.payloads)
    for p in numbered(20):
        t.publish(KEY, p)
    assert len(sink.payloads) == before  # all late …
    sink.wait(lambda items: len(items) == before + 20)
    assert sink.payloads[before:] == numbered(20)  # … and in order


def test_partition_isolates_and_withdraws_the_token_and_heal_restores(bus: MemoryBus, make: Callable) -> None:
    km, pl = make(agent="a_km"), make(agent="a_pl")
    to_km: list[bytes] = []
    to_pl: list[bytes] = []
    km.subscribe(keys.inbox_key("a_km"), lambda _k, p: to_km.append(p))
    pl.subscribe(keys.inbox_key("a_pl"), lambda _k, p: to_pl.append(p))
    seen_by_km: list[tuple[str, bool]] = []
    seen_by_pl: list[tuple[str, bool]] = []
    km.announce(keys.alive_key("a_km"))
    pl.announce(keys.alive_key("a_pl"))
    km.watch(keys.alive_key("a_pl"), lambda k, a: seen_by_km.append((k, a)))
    pl.watch(keys.alive_key("a_km"), lambda k, a: seen_by_pl.append((k, a)))
    assert seen_by_km == [(keys.alive_key("a_pl"), True)] and seen_by_pl == [(keys.alive_key("a_km"), True)]

    km.update(FaultUpdate(set_services={"a_km": NetFaults(partition=True)}))
    assert keys.alive_key("a_km") not in bus.alive()  # a_km looks gone …
    assert seen_by_pl[-1] == (keys.alive_key("a_km"), False)
    assert seen_by_km[-1] == (keys.alive_key("a_pl"), False)  # … and the others look gone to it
    km.publish(keys.fipa_key("C4", "a_km", "a_pl"), b"out")
    pl.publish(keys.fipa_key("C4", "a_pl", "a_km"), b"in")
    assert to_pl == [] and to_km == []
    assert km.applied["partition_out"] == 1 and km.applied["partition_in"] == 1

    km.update(FaultUpdate(clear_services=["a_km"]))
    assert keys.alive_key("a_km") in bus.alive()
    assert seen_by_pl[-1] == (keys.alive_key("a_km"), True)
    assert seen_by_km[-1] == (keys.alive_key("a_pl"), True)
    km.publish(keys.fipa_key("C4", "a_km", "a_pl"), b"out")
    pl.publish(keys.fipa_key("C4", "a_pl", "a_km"), b"in")
    assert to_pl == [b"out"] and to_km == [b"in"]


def test_partitioned_from_the_start_never_announces(bus: MemoryBus, make: Callable) -> None:
    km = make(FaultSettings(services={"a_km": NetFaults(partition=True)}))
    km.announce(keys.alive_key("a_km"))
    assert bus.alive() == set()
    km.update(FaultUpdate(clear_services=["*"]))
    assert bus.alive() == {keys.alive_key("a_km")}


def test_clear_restores_the_fast_path(bus: MemoryBus, make: Callable) -> None:
    sink = Sink(bus, KEY)
    t = make(channel(drop=1.0, corrupt=1.0))
    t.publish(KEY, b"a")
    assert t.active and sink.payloads == []
    t.update(FaultUpdate(clear_channels=["*"], clear_services=["*"]))
    assert not t.active
    t.publish(KEY, b"b")
    assert sink.payloads == [b"b"]


def test_events_name_the_communicate(bus: MemoryBus, make: Callable) -> None:
    events = Sink(bus, EVENT_ALL)
    t = make(channel(drop=1.0))
    msg = communicate(Performative.INFORM, "a_km", "a_pl", "fipa-query", "conv-42")
    t.publish(KEY, encode(msg))
    events.wait(lambda items: len(items) == 2)
    ev = events_of(events)[1]
    assert (ev.kind, ev.agent, ev.channel, ev.key) == ("drop", "a_km", "C4", KEY)
    assert ev.conversation_id == "conv-42" and ev.performative == "inform"
    assert events.items[1][0] == "roco/fault/event/a_km"


def test_live_control_over_the_control_keys(bus: MemoryBus, make: Callable) -> None:
    sink, states = Sink(bus, KEY), Sink(bus, STATE_ALL)
    t = make()
    update = FaultUpdate(set_channels={"C4": MessageFaults(drop=1.0)}, request="r1")
    bus.publish(CONTROL_ALL, msgspec.json.encode(update))  # as `roco fault msg` does
    states.wait(lambda items: len(items) == 1)
    report = msgspec.json.decode(states.payloads[0], type=FaultReport)
    assert report.agent == "a_km" and report.request == "r1" and report.channels["C4"].drop == 1.0
    t.publish(KEY, b"gone")
    assert sink.payloads == []
    bus.publish(control_key("a_pl"), msgspec.json.encode(FaultUpdate(clear_channels=["*"], request="r2")))
    bus.publish(control_key("a_km"), msgspec.json.encode(FaultUpdate(clear_channels=["*"], request="r3")))
    states.wait(lambda items: len(items) == 2)
    assert msgspec.json.decode(states.payloads[1], type=FaultReport).request == "r3"  # not r2: for a_pl
    t.publish(KEY, b"back")
    assert sink.payloads == [b"back"]
    bus.publish(CONTROL_ALL, b"{not json")  # ignored with a warning
    bus.publish(CONTROL_ALL, msgspec.json.encode(FaultUpdate(request="r4")))
    states.wait(lambda items: len(items) == 3)


def test_settings_parse_and_validate() -> None:
    s = parse_settings('{"seed": 5, "channels": {"C3": {"drop": 0.5}}, "services": {"a_km": {"delay_s": 1}}}')
    assert s.channels["C3"].drop == 0.5 and s.services["a_km"].delay_s == 1.0 and s.seed == 5
    assert settings_from_env({}) == FaultSettings()
    for bad in (
        '{"channels": {"C3": {"drop": 1.5}}}',
        '{"channels": {"C3": {"dorp": 0.1}}}',
        "[",
        '{"x": 1}',
    ):
        with pytest.raises(ValueError) as info:
            parse_settings(bad)
        assert "\n" not in str(info.value)
