"""The pieces of two hosts on one machine (services/hosts/): the delaying relay (loopback, no
root), the namespaces' life and clean-up and the link's cut (root), the report's timeline rows
of the link, and `roco hosts` on bad input."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.fleet.launcher import free_port
from services.hosts import link
from services.hosts.netns import HostPair, run_ip, sweep
from services.recorder.record import read_link_bytes, read_link_events
from services.report.timeline import link_events
from tests.support.machine import needs_two_hosts


def _echo_server() -> tuple[socket.socket, int]:
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    return srv, srv.getsockname()[1]


def test_the_relay_delays_each_direction_and_keeps_the_order() -> None:
    srv, port = _echo_server()
    relay_port = free_port()
    relay = subprocess.Popen(
        [sys.executable, "-m", "services.hosts.relay", "--listen", f"127.0.0.1:{relay_port}",
         "--to", f"127.0.0.1:{port}", "--delay-ms", "50", "--jitter-ms", "10"],
        stdout=subprocess.PIPE,
    )  # fmt: skip
    try:
        assert relay.stdout is not None and b"roco relay" in relay.stdout.readline()
        client = socket.create_connection(("127.0.0.1", relay_port), timeout=5)
        conn, _ = srv.accept()
        rtts, received = [], b""
        for i in range(10):
            t0 = time.monotonic()
            client.sendall(bytes([i]) * 10)
            data = b""
            while len(data) < 10:
                data += conn.recv(10 - len(data))
            conn.sendall(data)
            back = b""
            while len(back) < 10:
                back += client.recv(10 - len(back))
            rtts.append(time.monotonic() - t0)
            received += back
        assert received == b"".join(bytes([i]) * 10 for i in range(10))
        assert min(rtts) >= 0.080  # 2 × (50 − 10) ms at least (no upper bound: scripts/bench_relay.py)
        client.close()
        conn.close()
    finally:
        relay.terminate()
        relay.wait()
        srv.close()


def test_the_relay_counts_what_it_forwards_each_way_per_second(tmp_path: Path) -> None:
    """``--count``: the bytes forwarded client → server (``up``) and back (``down``), per second
    of the clock, written as the relay stops (services/hosts/relay.py)."""
    srv, port = _echo_server()
    relay_port = free_port()
    count = tmp_path / "link_bytes.jsonl"
    relay = subprocess.Popen(
        [sys.executable, "-m", "services.hosts.relay", "--listen", f"127.0.0.1:{relay_port}",
         "--to", f"127.0.0.1:{port}", "--count", str(count)],
        stdout=subprocess.PIPE,
    )  # fmt: skip
    try:
        assert relay.stdout is not None and b"roco relay" in relay.stdout.readline()
        client = socket.create_connection(("127.0.0.1", relay_port), timeout=5)
        conn, _ = srv.accept()
        client.sendall(b"u" * 3000)
        got = b""
        while len(got) < 3000:
            got += conn.recv(4096)
        conn.sendall(b"d" * 700)
        back = b""
        while len(back) < 700:
            back += client.recv(4096)
        client.close()
        conn.close()
    finally:
        relay.terminate()
        relay.wait()
        srv.close()
    seconds = read_link_bytes(tmp_path)
    assert sum(s.up for s in seconds) == 3000 and sum(s.down for s in seconds) == 700
    assert all(float(s.t).is_integer() for s in seconds)


def test_link_events_become_timeline_rows() -> None:
    t0 = 1000.0
    entries = [
        {"t": 1000.5, "event": "shaping", "delay_ms": 20, "jitter_ms": 5, "loss_pct": 1, "how": "tc netem"},
        {"t": 1004.0, "event": "down", "seconds": 10},
        {"t": 1014.1, "event": "up"},
        {"t": 1020.0, "event": "down", "seconds": None},
        {"event": "up"},  # no time: ignored
    ]
    rows = link_events(entries, t0)
    assert [r.kind for r in rows] == ["link_shaping", "link_down", "link_down"]
    assert "20 ± 5 ms each way, 1 % loss" in rows[0].text and rows[0].start == pytest.approx(0.5)
    assert (rows[1].start, rows[1].end) == (pytest.approx(4.0), pytest.approx(14.1))
    assert "10.1 s" in rows[1].text
    assert rows[2].end is None and "not mended" in rows[2].text


@needs_two_hosts
def test_a_pair_left_by_a_killed_maker_is_swept_and_a_cut_is_undone(tmp_path: Path) -> None:
    code = (
        "import os\nfrom services.hosts.netns import HostPair\n"
        "p = HostPair.create()\nprint(p.tag, flush=True)\nos._exit(0)"
    )
    tag = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    left = HostPair(tag, 0, 0)
    assert left.exists()
    assert tag in sweep()
    assert not left.exists()
    assert run_ip("link", "show", left.uplink_dev[0], check=False).returncode != 0  # its veths went too

    pair = HostPair.create()
    try:
        robot = pair.link_addr("robot")
        ping = [*("ip", "netns", "exec", pair.netns("brain")), sys.executable, "-c",
                f"import socket; socket.create_connection(('{robot}', 9), timeout=1)"]  # fmt: skip
        # nothing listens on the robot's port 9: reachable = refused at once, cut = timed out
        assert "refused" in subprocess.run(ping, capture_output=True, text=True).stderr.lower()
        link.partition(pair, tmp_path, None)
        assert link.is_cut(pair)
        assert "timed out" in subprocess.run(ping, capture_output=True, text=True).stderr.lower()
        link.heal(pair, tmp_path)
        assert not link.is_cut(pair)
        assert [e["event"] for e in read_link_events(tmp_path)] == ["down", "up"]
    finally:
        pair.destroy()
    assert not pair.exists()


def test_roco_hosts_without_a_fleet_says_so_in_one_line(tmp_path: Path) -> None:
    for cmd in (["status"], ["partition", "5"], ["heal"], ["down"]):
        result = CliRunner().invoke(app, ["hosts", *cmd, "--runs-dir", str(tmp_path)])
        assert result.exit_code == 2, (cmd, result.output)
        assert result.output.strip().startswith("roco: no two-host fleet is up"), result.output
        assert len(result.output.strip().splitlines()) == 1
    bad = CliRunner().invoke(
        app, ["hosts", "up", "--delay-ms", "5", "--jitter-ms", "10", "--runs-dir", str(tmp_path)]
    )
    assert bad.exit_code == 2 and "jitter" in bad.output
