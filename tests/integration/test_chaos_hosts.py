"""Issue 21, "Chaos across hosts": ``roco chaos --hosts`` runs the chaos scenario on the two hosts
of ``roco hosts`` (brain and robot in network namespaces, link 20 ± 5 ms and 1 % loss, routers
meshed over mutual TLS, access control on) and faults a process of the robot's host, the brain's
router and the link itself during a pour (a pause of a_ta, a pause of the brain's router, a
cut of the link: faults the two hosts ride out; kills and restarts across hosts are in
docs/recovery.md, with what they still lose); the verdict holds (task done, no command lost, nothing
executed twice, no object dropped, record intact), and chaos.md says which host each fault hit
and when the link was down (as link.jsonl recorded it).

Needs root and iproute2 + nftables (.ci/run installs them); skipped only where namespaces cannot
be made. One run (≈ 1 min)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from services.hosts.netns import unavailable
from services.recorder.record import read_link_events
from services.scenario.chaos import CHAOS_FILE

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(unavailable() is not None, reason=f"two hosts: {unavailable()}"),
]
SERVICES = ("a_ta", "router_brain", "link")


def test_chaos_across_two_hosts_faults_both_hosts_and_the_link_and_keeps_everything(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "services.cli", "chaos", "--hosts", "--seed", "4", "--quiet"]
    opts = ["--services", ",".join(SERVICES), "--kinds", "pause", "--gap", "1,3"]
    proc = subprocess.run(
        [*cmd, *opts, "--runs-dir", str(tmp_path)], capture_output=True, text=True, timeout=900
    )
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    report = (run_dir / CHAOS_FILE).read_text()
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "**no**" not in report and "| record intact | yes (" in report
    rows = {r[3].strip(): r for r in (line.split("|") for line in report.splitlines()) if len(r) == 10}
    assert set(rows) >= set(SERVICES), report
    assert rows["a_ta"][2].strip() == "robot" and rows["router_brain"][2].strip() == "brain"
    assert rows["link"][2].strip() == "brain ↔ robot" and rows["link"][4].strip() == "cut"
    assert rows["link"][8].strip() == "yes"  # the first fault, 1–3 s into a pour of ≥ 12 s
    for name in ("a_ta", "router_brain"):  # paused and let run again: the same process
        assert rows[name][4].strip() == "pause" and 0.5 <= float(rows[name][5]) <= 4.0, rows[name]
    # the cut is in the run folder's link.jsonl, and chaos.md says when, in the run's seconds
    events = [e["event"] for e in read_link_events(run_dir)]
    assert events == ["shaping", "down", "up"], events
    cut_s = float(rows["link"][5])
    assert 2.0 <= cut_s <= 6.0 and "- link down from t = " in report
    placed = json.loads((run_dir / "hosts.json").read_text())["hosts"]
    assert {"a_ta", "ag_ex"} <= set(placed["robot"]["processes"])
    left = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert not [h for h in ("brain", "robot") if placed[h]["netns"] in left], "namespaces left behind"
