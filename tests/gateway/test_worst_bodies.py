"""The worst requests a hostile peer sends, against ``roco gateway`` as a process of a fleet
with access control (a router; no agents): each is answered with its status (4xx, or 200 for a message the
gateway refuses in FIPA terms), costs the gateway at most 100 MiB of peak RSS over its RSS
before and at most 1 s of CPU time until the next valid message is answered, and is counted
in the counters ``roco status`` shows. The bounds are the gateway's targets; the benchmark
(services/bench/gateway.py, ``roco bench --only gateway``) measures the same requests."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.bench.gateway import GatewayProcess, Inbox, message, post_now, worst_requests
from services.gateway.bridge import summary

MAX_RSS_GROWTH_MIB = 100.0
MAX_CPU_S = 1.0


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux /proc (clear_refs)")
def test_each_worst_request_is_refused_cheaply_counted_and_the_next_message_answered(tmp_path: Path) -> None:
    gateway = GatewayProcess.start(tmp_path)
    inbox = Inbox()
    try:
        attacks = worst_requests(gateway.url, "http://127.0.0.1:9/acc")
        costs: dict[str, tuple[int, float, float]] = {}
        for i, (name, (data, _expected)) in enumerate(attacks.items()):
            gateway.reset_peak()
            rss_kb, cpu = gateway.status()["VmRSS"], gateway.cpu_s()
            status = post_now(gateway.address, data)
            valid = message(
                gateway.url, "da0@host:1099/JADE", "a_co", "bring me the cup", f"c{i}", inbox.address
            )
            assert post_now(gateway.address, valid) == 200, name
            inbox.next()  # the gateway's refuse (a_co may not be addressed): it is up and answering
            growth = (gateway.status()["VmHWM"] - rss_kb) / 1024
            costs[name] = (status, growth, gateway.cpu_s() - cpu)
        assert {n: c[0] for n, c in costs.items()} == {n: e for n, (_, e) in attacks.items()}
        assert {n: c for n, c in costs.items() if c[1] > MAX_RSS_GROWTH_MIB or c[2] > MAX_CPU_S} == {}

        counters = gateway.counters()
        expected: dict[str, int] = {}
        for _data, status in attacks.values():
            expected[f"http.{status}"] = expected.get(f"http.{status}", 0) + 1
        expected["http.200"] += len(attacks)  # the valid messages
        assert {k: counters.get(k, 0) for k in expected} == expected
        assert counters["refused.sender"] == 1 and counters["post_skipped.roco_address"] == 1
        assert not counters.get("internal_errors")
        line = summary(counters)
        assert "http refused" in line and all(f"{s} " in line for s in (400, 403, 406, 431))
        command = ["status", "--router", gateway.endpoint, "--credentials", str(gateway.fleet.security)]
        done = subprocess.run(  # the operator's view: roco status, the gateway's line
            [sys.executable, "-m", "services.cli", *command],
            capture_output=True,
            text=True,
            timeout=60,
            env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
        )
        (shown,) = [row for row in done.stdout.splitlines() if row.startswith("gateway ")]
        assert "alive" in shown and "http refused" in shown and "406 " in shown, done.stdout + done.stderr
    finally:
        inbox.close()
        gateway.stop()
