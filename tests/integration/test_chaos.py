"""Faults on the local launcher: a chaos run that kills or restarts the agents that do
not move the robot — a_hi, a_co, a_pl, a_km — and the traffic recorder, each once, at random
times during the pour, ends with the task done, no command lost, nothing executed twice, no
object dropped and the traffic record intact (``roco chaos``; everything real: router,
recorder, one process per agent, MuJoCo). The record then holds exactly what each agent's
last process says it put on Zenoh (its ``published`` counter, ``counters.json``), each record
paired with its own bytes, and it conforms to the specification in full (``roco spec verify``).
Faults of a_ta and ag_ex are in docs/recovery.md."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.report.load import load_run
from services.runtime.counters import read_counters
from services.scenario.chaos import CHAOS_FILE
from services.spec_check.conformance import verify_report

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
SERVICES = ("a_hi", "a_co", "a_pl", "a_km", "recorder")
# all five while the robot works: paced to wall time, the pour lasts its ≈ 50 s of simulated
# time however fast the machine computes it
OPTS = ("--quiet", "--realtime", "--gap", "1,3", "--kinds", "kill,restart")


def test_each_agent_that_does_not_move_the_robot_killed_or_restarted_during_a_pour(tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "chaos",
            "--seed",
            "5",
            "--services",
            ",".join(SERVICES),
            *OPTS,
            "--runs-dir",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=1500,
    )
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    report = (run_dir / CHAOS_FILE).read_text()
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    rows = [line.split("|") for line in report.splitlines() if line.startswith("| ") and " → " in line]
    assert sorted(r[2].strip() for r in rows) == sorted(SERVICES)
    for r in rows:  # each one killed or restarted: a new process each time
        before, after = r[5].split("→")
        assert r[3].strip() in ("kill", "restart") and before.strip() != after.strip()
    assert "| faults during the command | 5 of 5 |" in report and "**no**" not in report
    assert "| record intact | yes (" in report and "2 recorder incarnations" in report
    # a_co came back with the accepted command and carried it to the end
    assert "restored 1 command(s)" in (run_dir / "logs" / "a_co.log").read_text()

    # the record holds exactly what each agent's last process put on Zenoh up to its report,
    # each record paired with its own bytes
    run = load_run(run_dir)
    assert run.integrity.intact and run.integrity.paired == len(run.messages) > 100
    for m in run.messages:
        assert m.comm is not None and (m.comm.conversation_id, m.comm.performative.value) == (
            m.rec.conversation_id,
            m.rec.performative,
        )
    counters = read_counters(run_dir)
    assert set(counters) == {"a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex"}
    for agent, rep in counters.items():
        mine = [
            m
            for m in run.messages
            if m.rec.source is not None
            and m.rec.source.split(":")[0] == rep.session
            and m.rec.t_sent is not None
            and m.rec.t_sent <= rep.time
        ]
        assert {m.rec.sender for m in mine} <= {agent}
        # a process restarted after its last conversation has published nothing: 0 == 0
        assert len(mine) == rep.counters.get("published", 0), agent
    for busy in ("a_ta", "ag_ex"):  # never faulted here, and they talk throughout the pour
        assert counters[busy].counters["published"] > 0, busy

    # a_ta, never faulted, is reproduced from the record the two recorder incarnations wrote
    # (each communicate once); the agents restarted are replayed as one process each, which
    # their restarts make differ
    from services.replay.driver import render, replay

    replayed = replay(run_dir, "a_ta")
    assert replayed.equal, render(replayed)

    # and the record conforms to the specification: a subscribe that reached no process (its
    # receiver killed) is listed as lost with it, not as unanswered
    conforms, text = verify_report(run_dir)
    assert conforms, text[-4000:]
