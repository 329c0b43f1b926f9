"""Fault events travel inside the recorder's sync (services/recorder/sync.py ``record``): the
recorder's loop (services/recorder/recorder.py ``_Loop``) writes the events a sync carries,
once per token, before it answers, so the answer means "written" even when puts are lost — as
after a router restart, when the fault events' put was lost and the sync was answered
(tests/fault/test_record_after_router_restart.py). Here the Zenoh session is a stand-in that
loses the puts it is told to, and hands the others to a real ``_Loop`` on its own thread."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import msgspec
import pytest
import zenoh

from services.fault.process import INJECTOR, record_events
from services.recorder import sync
from services.recorder.record import read_fault_events
from services.recorder.recorder import TrafficWriter, _Loop
from services.runtime import keys
from services.runtime.faults import FaultEvent, event_key
from services.runtime.transport import ZenohTransport
from tests.support.zenoh_sample import Sample, sample


@dataclass
class _Sub:
    owner: LossySession
    callback: Callable[[Sample], Any]

    def undeclare(self) -> None:
        self.owner.subs.remove(self)


@dataclass
class LossySession:
    """A session to the recorder's loop: puts on the recorder's keys go into ``loop``'s inbox,
    its answers to this session's subscribers; ``lose(key, n)`` makes the next ``n`` puts on
    ``key`` (or the next ``n`` answers, on ``roco/recorder/synced``) vanish."""

    loop: _Loop | None = None
    subs: list[_Sub] = field(default_factory=list)
    losing: dict[str, int] = field(default_factory=dict)
    answers: list[bytes] = field(default_factory=list)

    def lose(self, key: str, n: int) -> None:
        self.losing[key] = n

    def _lost(self, key: str) -> bool:
        prefix = key.rsplit("/", 1)[0] if key.startswith("roco/fault/event/") else key
        n = self.losing.get(prefix, 0)
        if n:
            self.losing[prefix] = n - 1
        return n > 0

    def declare_subscriber(self, key: str, callback: Callable[[Sample], Any]) -> _Sub:
        assert key == keys.RECORDER_SYNCED
        sub = _Sub(self, callback)
        self.subs.append(sub)
        return sub

    def put(self, key: str, payload: bytes) -> None:
        if not self._lost(key):
            assert self.loop is not None
            self.loop.put(key, payload)

    def publish(self, key: str, payload: bytes) -> None:  # the recorder's transport
        assert key == keys.RECORDER_SYNCED
        self.answers.append(payload)
        if not self._lost(key):
            for sub in list(self.subs):
                sub.callback(sample(payload))


@pytest.fixture
def recorder(tmp_path: Path) -> Iterator[LossySession]:
    session = LossySession()
    writer = TrafficWriter(tmp_path)
    loop = _Loop(writer, cast(ZenohTransport, session))
    session.loop = loop
    thread = threading.Thread(target=loop.run, name="recorder loop")
    thread.start()
    try:
        yield session
    finally:
        loop.inbox.put(None)
        thread.join(10)
        writer.close()


EVENTS = [
    FaultEvent(t=1.0, agent=INJECTOR, kind="kill", target="router"),
    FaultEvent(t=2.0, agent=INJECTOR, kind="start", target="router"),
]


def _kinds(run_dir: Path) -> list[tuple[str, str | None]]:
    events, bad = read_fault_events(run_dir)
    assert bad == 0
    return [(e.kind, e.target) for e in events]


def _zenoh(session: LossySession) -> zenoh.Session:
    return cast(zenoh.Session, session)


def test_events_are_written_when_their_own_puts_would_be_lost(recorder: LossySession, tmp_path: Path) -> None:
    # as after the router restart: nothing on roco/fault/event/* arrives, and the first sync
    # is lost too; the answer comes only once the events are in faults.jsonl
    recorder.lose("roco/fault/event", 1000)
    recorder.lose(keys.RECORDER_SYNC, 1)
    assert record_events(_zenoh(recorder), EVENTS, sync_timeout=10.0)
    assert _kinds(tmp_path) == [("kill", "router"), ("start", "router")]


def test_a_sync_sent_again_writes_its_events_once(recorder: LossySession, tmp_path: Path) -> None:
    recorder.lose(keys.RECORDER_SYNCED, 2)  # the first two answers are lost: sent three times
    assert sync.record(_zenoh(recorder), EVENTS, timeout=10.0)
    assert len(recorder.answers) == 3
    assert _kinds(tmp_path) == [("kill", "router"), ("start", "router")]


def test_many_events_travel_in_several_syncs(recorder: LossySession, tmp_path: Path) -> None:
    many = [FaultEvent(t=float(i), agent=INJECTOR, kind="pause", target=f"s{i}") for i in range(150)]
    assert sync.record(_zenoh(recorder), many, timeout=10.0)
    assert len(recorder.answers) == 3  # 64 + 64 + 22
    assert [t for _, t in _kinds(tmp_path)] == [f"s{i}" for i in range(150)]


def test_a_bare_token_is_answered_as_before(recorder: LossySession, tmp_path: Path) -> None:
    assert sync.sync(_zenoh(recorder), timeout=10.0)
    assert len(recorder.answers) == 1 and len(recorder.answers[0]) == 32
    assert not (tmp_path / "faults.jsonl").exists()


@pytest.mark.parametrize(
    "payload",
    [
        b'{"token": "t0", "events": []' + b" " * sync.MAX_SYNC_BYTES + b"}",  # valid, too big
        b'{"token": "t1", "events": "none"}',
        b'{"token": "", "events": []}',
        msgspec.json.encode(sync.SyncRequest(token="t2", events=[FaultEvent(t=1.0, agent="a_co", kind="x")])),
    ],
    ids=["too-big", "malformed", "no-token", "another-agent"],
)
def test_a_bad_sync_is_neither_written_nor_answered(
    recorder: LossySession, tmp_path: Path, payload: bytes
) -> None:
    recorder.put(keys.RECORDER_SYNC, payload)
    assert sync.sync(_zenoh(recorder), timeout=10.0)  # after it: the loop went on
    assert len(recorder.answers) == 1 and not (tmp_path / "faults.jsonl").exists()


def test_events_on_their_own_key_are_still_written(recorder: LossySession, tmp_path: Path) -> None:
    # an agent's faults (services/runtime/faults.py FaultyTransport) come on roco/fault/event/<agent>
    recorder.put(event_key("a_km"), msgspec.json.encode(FaultEvent(t=1.0, agent="a_km", kind="drop")))
    assert sync.sync(_zenoh(recorder), timeout=10.0)
    assert _kinds(tmp_path) == [("drop", None)]
