"""Issue 8's test: a fuzz run of 10,000 malformed communicates per agent during a live pour
(router, one process per agent, MuJoCo executor; a fuzzer process with its own Zenoh
session) leaves the task successful and every agent alive, and the agents' counters show
the rejects."""

from __future__ import annotations

import queue
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
import zenoh

from services.fleet.launcher import AGENT_ORDER, Fleet, free_port
from services.monitor import is_world_update
from services.runtime import keys
from services.runtime.counters import ask_counters
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport
from services.runtime.session import alive_agents, open_client

pytestmark = pytest.mark.slow
PER_AGENT = 10_000


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[tuple[Fleet, zenoh.Session]]:
    (tmp_path / "logs").mkdir()
    # without access control: the fuzzer puts on other agents' keys, as a peer would whose
    # credentials were stolen (with access control on, the router refuses its session)
    f = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=False)
    f.start_router()
    session = open_client(f.endpoint)
    try:
        knowledge = threading.Event()
        session.declare_subscriber(
            keys.fipa_key("C6", "a_ta", "a_km"),
            lambda s: knowledge.set() if is_world_update(s.payload.to_bytes()) else None,
        )
        f.start_agents(AGENT_ORDER)
        f.wait_alive(session, AGENT_ORDER, timeout=120)
        assert knowledge.wait(120), "no initial knowledge"
        yield f, session
    finally:
        session.close()
        f.stop()


def test_ten_thousand_malformed_communicates_per_agent_during_a_pour(
    fleet: tuple[Fleet, zenoh.Session],
) -> None:
    f, session = fleet
    reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
    dec = msgspec.json.Decoder(HumanReport)
    session.declare_subscriber(keys.HUMAN_OUT, lambda s: reports.put(dec.decode(s.payload.to_bytes())))
    fuzzer = subprocess.Popen(
        [sys.executable, "-m", "tests.fuzz.fuzzer", f.endpoint, str(PER_AGENT)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        session.put(
            keys.HUMAN_IN, msgspec.json.encode(HumanInput(text="pour the jar into the bowl", request_id="fz"))
        )
        while True:
            report = reports.get(timeout=150)
            if report.request_id == "fz" and report.kind in FINAL_REPORTS:
                break
        out, _ = fuzzer.communicate(timeout=150)
    finally:
        if fuzzer.poll() is None:
            fuzzer.kill()
            fuzzer.wait()
    assert fuzzer.returncode == 0, out[-2000:]
    assert report.kind.value == "succeeded", report
    assert f.dead() == [] and set(AGENT_ORDER) <= alive_agents(session)
    counters = ask_counters(session, AGENT_ORDER, timeout=60)
    assert set(counters) == set(AGENT_ORDER)
    for agent in AGENT_ORDER:
        c = counters[agent].counters
        rejected = sum(v for k, v in c.items() if k.startswith("rejected."))
        # byte-identical fuzz (a short truncation drawn twice) is dropped as a duplicate
        assert rejected + c.get("duplicates", 0) >= PER_AGENT, (agent, c)
        assert c.get("rejected.internal", 0) == 0, (agent, c)
        assert c.get("behaviour_errors", 0) == 0, (agent, c)
    # the CLI shows them
    status = subprocess.run(
        [sys.executable, "-m", "services.cli", "status", "--router", f.endpoint, "--counters-timeout", "30"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert status.returncode == 0, status.stdout + status.stderr
    assert "a_km      alive  received" in status.stdout and "malformed" in status.stdout
