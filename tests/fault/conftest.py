"""A small real fleet for the fault tests: a Zenoh router on a free loopback port (no
multicast), the traffic recorder and a_km as separate processes (spawn semantics), with the
state file ``roco up`` leaves (``runs/.fleet.json``) so that ``roco fault`` finds it."""

from __future__ import annotations

import queue
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import msgspec
import pytest
import zenoh

from services.fault.process import FLEET_FILE, UpFleet, is_service_process, proc_state
from services.fleet.launcher import Fleet, free_port
from services.recorder.record import read_fault_events
from services.runtime import keys
from services.runtime.faults import FaultEvent
from services.runtime.session import alive_agents, open_client
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages.l_wm import ObjectQuery
from tests.support.messages import communicate


@dataclass
class LiveFleet:
    fleet: Fleet
    session: zenoh.Session
    runs_dir: Path
    replies: queue.SimpleQueue[Communicate]

    @property
    def endpoint(self) -> str:
        return self.fleet.endpoint

    @property
    def run_dir(self) -> Path:
        return self.fleet.run_dir

    def roco(self, *args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
        """``roco fault ARGS… --runs-dir RUNS`` in a process of its own."""
        return subprocess.run(
            [sys.executable, "-m", "services.cli", "fault", *args, "--runs-dir", str(self.runs_dir)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    def query(self, n: str) -> None:
        """Ask a_km, as a_pl, where the jar is (conversation ``n``, reply-with ``n``)."""
        msg = communicate(
            Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", n, ObjectQuery("jar"), reply_with=n
        )
        self.session.put(keys.fipa_key("C4", "a_pl", "a_km"), encode(msg))

    def answer(self, n: str, timeout: float = 30.0) -> list[Communicate]:
        """Replies up to and including the one to query ``n`` (earlier ones first)."""
        got = []
        deadline = time.monotonic() + timeout
        while True:
            reply = self.replies.get(timeout=max(0.0, deadline - time.monotonic()))
            got.append(reply)
            if reply.in_reply_to == n:
                return got

    def wait_alive(self, name: str, alive: bool = True, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while (name in alive_agents(self.session, timeout=0.5)) != alive:
            if time.monotonic() > deadline:
                raise AssertionError(f"{name} {'not alive' if alive else 'still alive'} after {timeout} s")
            time.sleep(0.05)

    def sync_recorder(self, timeout: float) -> bool:
        """Ask the recorder to confirm it wrote everything routed to it so far (sync token)."""
        token = uuid.uuid4().hex.encode()
        synced: queue.SimpleQueue[bool] = queue.SimpleQueue()
        sub = self.session.declare_subscriber(
            keys.RECORDER_SYNCED, lambda s: synced.put(True) if s.payload.to_bytes() == token else None
        )
        try:
            self.session.put(keys.RECORDER_SYNC, token)
            return synced.get(timeout=timeout)
        except queue.Empty:
            return False
        finally:
            sub.undeclare()

    def recorded_faults(
        self, until: Callable[[list[FaultEvent]], bool], timeout: float = 30.0
    ) -> list[FaultEvent]:
        """The run folder's fault events once ``until(events)`` holds: syncs with the
        recorder, reads, repeats until the deadline (events of other processes may reach the
        recorder after the sync token)."""
        deadline = time.monotonic() + timeout
        while True:
            self.sync_recorder(max(0.1, deadline - time.monotonic()))
            events, _ = read_fault_events(self.run_dir)
            if until(events):
                return events
            if time.monotonic() > deadline:
                raise AssertionError(f"fault record incomplete after {timeout} s: {events}")


@pytest.fixture
def live(tmp_path: Path) -> Iterator[LiveFleet]:
    runs_dir = tmp_path / "runs"
    run_dir = runs_dir / "run"
    (run_dir / "logs").mkdir(parents=True)
    # forged traffic and tokens from the test: no access control (tested in tests/security/)
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", env={"ROCO_RERUN": "0"}, acl=False)
    session: zenoh.Session | None = None
    try:
        fleet.start_router()
        session = open_client(fleet.endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        fleet.start_agents(["a_km"])
        fleet.wait_alive(session, ["a_km"], timeout=60)
        state = {"endpoint": fleet.endpoint, "run_dir": str(run_dir), "pids": fleet.pids()}
        (runs_dir / FLEET_FILE).write_bytes(msgspec.json.encode(state))
        replies: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        session.declare_subscriber(
            keys.fipa_key("C4", "a_km", "a_pl"), lambda s: replies.put(decode(s.payload.to_bytes()))
        )
        yield LiveFleet(fleet, session, runs_dir, replies)
    finally:
        if session is not None:
            session.close()
        _stop_started_later(fleet, runs_dir)
        fleet.stop()


def _stop_started_later(fleet: Fleet, runs_dir: Path) -> None:
    """End the processes `roco fault start` started (their PIDs are only in the state file)."""
    try:
        up = UpFleet.load(runs_dir)
    except Exception:
        return
    import os
    import signal

    ours = {p.pid for p in fleet.processes.values()}
    for name, pid in up.pids.items():
        if pid in ours or not is_service_process(pid, name, up.endpoint):
            continue
        os.kill(pid, signal.SIGCONT)
        os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + 10
        while proc_state(pid) not in (None, "Z") and time.monotonic() < deadline:
            time.sleep(0.05)
        if proc_state(pid) not in (None, "Z"):
            os.killpg(pid, signal.SIGKILL)
