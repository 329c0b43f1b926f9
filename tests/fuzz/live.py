"""The live fuzz with access control on: a pour by the whole fleet (router with
access control, recorder, six agent processes, MuJoCo) while a fuzzer process holding stolen
agents' credentials (tests/fuzz/fuzzer.py ``--identity``) floods every agent those identities
may reach with malformed communicates on their own keys, and tries keys they may not use.

Used by tests/fuzz/test_live_fuzz.py (fewer communicates, CI) and scripts/fuzz_live.py
(10,000 per agent, the figures of docs/security.md).
"""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import msgspec

from services.fleet.launcher import AGENT_ORDER, Fleet, free_port
from services.monitor import is_world_update
from services.recorder.record import read_records
from services.runtime import keys
from services.runtime.counters import CountersReport, ask_counters
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport
from services.runtime.refusals import RefusalReport, collect_reports
from services.runtime.session import alive_agents, open_client

IDENTITIES = ("a_co", "a_ta")
"""The compromised identities: between them they reach all six agents (a_co: a_hi, a_pl, a_ta;
a_ta: a_co, a_km, ag_ex)."""


@dataclass
class LiveFuzz:
    """What one live fuzz run gave: the pour's final report (None: none in time), the fuzzer's
    exit code, output and summary, every agent's counters, the router's refusals, the agents
    that died or lost their liveliness token, the traffic record's communicates whose claimed
    sender differs from their key's sender (by key sender), the wall time (s) and what
    ``roco status --credentials`` printed at the end."""

    report: HumanReport | None
    fuzzer_code: int
    fuzzer_output: str
    summary: dict[str, object]
    counters: dict[str, CountersReport]
    refusals: RefusalReport | None
    dead: list[str]
    spoofs_recorded: dict[str, int]
    seconds: float
    status: str


def run_live_fuzz(run_dir: Path, per_agent: int, forbidden: int, seed: int = 8) -> LiveFuzz:
    """Start the fleet with access control in ``run_dir``, fuzz ``per_agent`` communicates to
    each agent (and ``forbidden`` forbidden puts per identity) during a pour, stop the fleet."""
    (run_dir / "logs").mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=False)
    assert fleet.security is not None
    fleet.start_router()
    session = open_client(fleet.endpoint)  # the operator
    fuzzer: subprocess.Popen[str] | None = None
    try:
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        knowledge = threading.Event()
        session.declare_subscriber(
            keys.fipa_key("C6", "a_ta", "a_km"),
            lambda s: knowledge.set() if is_world_update(s.payload.to_bytes()) else None,
        )
        fleet.start_agents(AGENT_ORDER)
        fleet.wait_alive(session, AGENT_ORDER, timeout=120)
        if not knowledge.wait(120):
            raise RuntimeError("no initial knowledge within 120 s")
        reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
        dec = msgspec.json.Decoder(HumanReport)
        session.declare_subscriber(keys.HUMAN_OUT, lambda s: reports.put(dec.decode(s.payload.to_bytes())))
        args = [fleet.endpoint, str(per_agent), str(seed), "--forbidden", str(forbidden)]
        for name in IDENTITIES:
            args += ["--identity", name]
        fuzzer = subprocess.Popen(  # holds the stolen credentials: the deployment's folder
            [sys.executable, "-m", "tests.fuzz.fuzzer", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=dict(os.environ, ROCO_SECURITY=str(fleet.security)),
        )
        said = HumanInput(text="pour the jar into the bowl", request_id="fz")
        session.put(keys.HUMAN_IN, msgspec.json.encode(said))
        report: HumanReport | None = None
        deadline = time.monotonic() + 300
        while report is None and time.monotonic() < deadline:
            try:
                r = reports.get(timeout=max(0.1, deadline - time.monotonic()))
            except queue.Empty:
                break
            if r.request_id == "fz" and r.kind in FINAL_REPORTS:
                report = r
        out, _ = fuzzer.communicate(timeout=600)
        summary: dict[str, object] = {}
        for line in out.splitlines():
            if line.startswith("summary "):
                summary = json.loads(line.removeprefix("summary "))
        dead = fleet.dead() + sorted(set(AGENT_ORDER) - alive_agents(session))
        counters = ask_counters(session, AGENT_ORDER, timeout=60)
        refusals: list[RefusalReport] = []
        with collect_reports(session, refusals):
            session.put(keys.COUNTERS_ASK, b"")
        status = subprocess.run(
            [sys.executable, "-m", "services.cli", "status", "--router", fleet.endpoint,
             "--credentials", str(fleet.security), "--counters-timeout", "30"],
            capture_output=True, text=True, timeout=120,
            env={k: v for k, v in os.environ.items() if k != "ROCO_SECURITY"},
        )  # fmt: skip
    finally:
        if fuzzer is not None and fuzzer.poll() is None:
            fuzzer.kill()
            fuzzer.wait()
        session.close()
        fleet.stop()
    spoofs: dict[str, int] = {}
    for rec in read_records(run_dir):
        if rec.key_sender is not None and rec.sender != rec.key_sender:
            spoofs[rec.key_sender] = spoofs.get(rec.key_sender, 0) + 1
    return LiveFuzz(
        report=report,
        fuzzer_code=fuzzer.returncode if fuzzer is not None else -1,
        fuzzer_output=out,
        summary=summary,
        counters=counters,
        refusals=refusals[0] if refusals else None,
        dead=dead,
        spoofs_recorded=spoofs,
        seconds=time.monotonic() - t0,
        status=status.stdout + status.stderr,
    )
