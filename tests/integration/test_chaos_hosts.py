"""Chaos across hosts: ``roco chaos --hosts`` runs the chaos scenario on the two hosts
of ``roco hosts`` (brain and robot in network namespaces, link 20 ± 5 ms and 1 % loss, routers
meshed over mutual TLS, access control on) and faults both hosts and the link during one pour
(seed 136, 1–2 s apart): the robot's router killed (2.2 s: ag_ex and a_ta lose their router,
ag_ex holds position), a_ta restarted on the robot, the brain's router paused (1.1 s), the link
cut (4.4 s). The verdict holds (task done, no command lost, nothing executed twice, no object
dropped, record intact: what was put while a router was down is fetched from the robot-side
publishers' caches), the record conforms to the specification, every fault fell during the
command, and chaos.md says which host each fault hit and when the link was down (as link.jsonl
recorded it). The robot-side kills come first, before the pour's tilt: a tilt interrupted by
them is not kept (docs/recovery.md, "Across two hosts").

Needs root and iproute2 + nftables (.ci/run installs them); skipped only where namespaces cannot
be made. One run (≈ 30 s)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from services.recorder.record import read_fault_events, read_link_events
from services.scenario.chaos import CHAOS_FILE
from services.spec_check.conformance import verify_report
from tests.support.machine import needs_two_hosts

pytestmark = [pytest.mark.slow, pytest.mark.fleet, needs_two_hosts]
SERVICES = ("a_ta", "router_robot", "router_brain", "link")
KINDS = {"router_robot": "kill", "a_ta": "restart", "router_brain": "pause", "link": "cut"}
"""What seed 136 draws for ``SERVICES``, in this order."""


def test_chaos_across_two_hosts_faults_both_hosts_and_the_link_and_keeps_everything(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "services.cli", "chaos", "--hosts", "--seed", "136", "--quiet"]
    opts = ["--services", ",".join(SERVICES), "--kinds", "pause,kill,restart", "--gap", "1,2"]
    proc = subprocess.run(
        [*cmd, *opts, "--runs-dir", str(tmp_path)], capture_output=True, text=True, timeout=900
    )
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    report = (run_dir / CHAOS_FILE).read_text()
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "**no**" not in report and "| record intact | yes (" in report
    rows = {r[3].strip(): r for r in (line.split("|") for line in report.splitlines()) if len(r) == 10}
    assert set(rows) >= set(SERVICES), report
    hosts = {name: rows[name][2].strip() for name in SERVICES}
    robot, brain = ("a_ta", "router_robot"), ("router_brain",)
    assert hosts == {"link": "brain ↔ robot"} | dict.fromkeys(robot, "robot") | dict.fromkeys(brain, "brain")
    assert {name: rows[name][4].strip() for name in SERVICES} == KINDS
    assert [name for name in rows if name in KINDS] == list(KINDS)  # in the order drawn
    assert all(rows[name][8].strip() == "yes" for name in SERVICES), report  # all in the pour
    for name in ("a_ta", "router_robot"):  # killed or restarted: a new process
        before, after = (int(p) for p in rows[name][6].split("→"))
        assert before != after, rows[name]
    before, after = (int(p) for p in rows["router_brain"][6].split("→"))
    assert before == after  # paused and let run again: the same process
    # the cut is in the run folder's link.jsonl, and chaos.md says when, in the run's seconds
    events = [e["event"] for e in read_link_events(run_dir)]
    assert events == ["shaping", "down", "up", "counters"], events  # counters: read at hosts down
    cut_s = float(rows["link"][5])
    assert 2.0 <= cut_s <= 6.0 and "- link down from t = " in report
    # every fault is in the record too (faults.jsonl, report section 8), those of the routers
    # included: the runner records them once its session sees the recorder again
    recorded = {(e.target, e.kind) for e in read_fault_events(run_dir)[0]}
    assert {
        ("a_ta", "stop"),
        ("a_ta", "start"),
        ("router_robot", "kill"),
        ("router_robot", "start"),
        ("router_brain", "pause"),
        ("router_brain", "unpause"),
        ("link", "partition"),
        ("link", "heal"),
    } <= recorded, recorded
    placed = json.loads((run_dir / "hosts.json").read_text())["hosts"]
    assert {"a_ta", "ag_ex"} <= set(placed["robot"]["processes"])
    left = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert not [h for h in ("brain", "robot") if placed[h]["netns"] in left], "namespaces left behind"
    # and the record both hosts' routers fed conforms to the specification in full
    conforms, text = verify_report(run_dir)
    assert conforms, text[-4000:]
