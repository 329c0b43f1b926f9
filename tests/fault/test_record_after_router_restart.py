"""A fault of the router itself is recorded (services/fault/process.py ``record_events``): a
router and the traffic recorder of real processes; the router is killed and started again on
its endpoint, and the events are recorded at once. They travel inside the recorder's sync,
sent again until answered (services/recorder/sync.py ``record``): put on their own key, they
could reach the recorder's inbox after the sync, on another subscriber's thread, and the
answer came before they were written (seen: no router fault, or only the kill, in
faults.jsonl; tests/recorder/test_sync_events.py)."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator

import pytest

from services.fault.process import INJECTOR, record_events
from services.fleet.launcher import Fleet
from services.recorder.record import read_fault_events
from services.runtime.faults import FaultEvent
from services.runtime.session import open_client
from tests.support.router import router_fleet

pytestmark = [pytest.mark.fleet]


@pytest.fixture
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    fleets = router_fleet(tmp_path_factory, "recorded")
    f = next(fleets)
    f.start_recorder()
    session = open_client(f.endpoint)
    try:
        f.wait_alive(session, ["recorder"], timeout=60)
    finally:
        session.close()
    try:
        yield f
    finally:
        fleets.close()


def test_the_events_of_a_router_fault_are_recorded_once_the_router_is_back(fleet: Fleet) -> None:
    session = open_client(fleet.endpoint)
    try:
        router = fleet.processes["router"]
        os.kill(router.pid, signal.SIGKILL)
        router.wait(timeout=10)
        killed = FaultEvent(t=time.time(), agent=INJECTOR, kind="kill", target="router")
        fleet.start_router()
        started = FaultEvent(t=time.time(), agent=INJECTOR, kind="start", target="router")
        assert record_events(session, [killed, started])
    finally:
        session.close()
    events, bad = read_fault_events(fleet.run_dir)
    assert [(e.kind, e.target) for e in events] == [("kill", "router"), ("start", "router")] and bad == 0
