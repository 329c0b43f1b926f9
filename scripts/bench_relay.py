"""The round trip through the delaying relay (services/hosts/relay.py) on loopback, against the
delay it was given: a client sends 10 B through the relay to an echo server, which sends them
back through it; timed with ``time.monotonic`` from the send to the last byte back. Each
direction is held ``D ± J`` ms, so a round trip should take between 2 (D − J) and 2 (D + J) ms
plus loopback's own (tens of µs). No root needed.

Usage: ``python scripts/bench_relay.py [--delay-ms 50] [--jitter-ms 10] [--round-trips 50]``.
Exit 1 when the median round trip is above 2 (D + J) ms + ``SLACK_MS``.
"""

from __future__ import annotations

import argparse
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.fleet.launcher import free_port  # noqa: E402

SLACK_MS = 20.0
"""What the median round trip may take beyond 2 (D + J) ms: the relay's and the loopback's own
time, on a loaded machine."""
SIZE = 10
"""Bytes sent each round trip."""


def _read(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("the connection closed")
        data += chunk
    return data


def round_trips(delay_ms: float, jitter_ms: float, n: int) -> list[float]:
    """``n`` round trips (s) through a relay started with ``delay_ms`` and ``jitter_ms``."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    relay_port = free_port()
    to = f"127.0.0.1:{srv.getsockname()[1]}"
    relay = subprocess.Popen(
        [sys.executable, "-m", "services.hosts.relay", "--listen", f"127.0.0.1:{relay_port}", "--to", to,
         "--delay-ms", str(delay_ms), "--jitter-ms", str(jitter_ms)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,  # its stop, a connection still open, logs the cancelled pumps
        cwd=ROOT,
    )  # fmt: skip
    try:
        assert relay.stdout is not None and b"roco relay" in relay.stdout.readline()
        with socket.create_connection(("127.0.0.1", relay_port), timeout=10) as client:
            conn, _ = srv.accept()
            with conn:
                out = []
                for i in range(n):
                    t0 = time.monotonic()
                    client.sendall(bytes([i % 256]) * SIZE)
                    conn.sendall(_read(conn, SIZE))
                    _read(client, SIZE)
                    out.append(time.monotonic() - t0)
                return out
    finally:
        relay.terminate()
        relay.wait()
        srv.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--delay-ms", type=float, default=50.0)
    parser.add_argument("--jitter-ms", type=float, default=10.0)
    parser.add_argument("--round-trips", type=int, default=50)
    args = parser.parse_args()
    if args.delay_ms < 0 or args.jitter_ms < 0 or args.round_trips < 1:
        parser.error("delay and jitter are ≥ 0, round trips ≥ 1")
    rtts = sorted(r * 1e3 for r in round_trips(args.delay_ms, args.jitter_ms, args.round_trips))
    low, high = 2 * max(0.0, args.delay_ms - args.jitter_ms), 2 * (args.delay_ms + args.jitter_ms)
    median = statistics.median(rtts)
    print(f"# the relay's round trip on loopback ({time.strftime('%Y-%m-%d')})")
    print(f"Machine: {benchlib.machine()}")
    print(
        f"delay {args.delay_ms:g} ± {args.jitter_ms:g} ms each way: expected {low:g}–{high:g} ms a round trip"
    )
    print(
        f"{len(rtts)} round trips of {SIZE} B: min {rtts[0]:.1f} ms, median {median:.1f} ms, "
        f"p99 {rtts[int(0.99 * (len(rtts) - 1))]:.1f} ms, max {rtts[-1]:.1f} ms"
    )
    return 0 if median <= high + SLACK_MS else 1


if __name__ == "__main__":
    sys.exit(main())
