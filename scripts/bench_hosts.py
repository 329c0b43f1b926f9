"""Figures of the fleet on two hosts (docs/deploy.md, "Two hosts on one machine"): the round trip
across the link, the pour's wall time with and without shaping, and what a 10 s partition costs.

    .venv/bin/python scripts/bench_hosts.py [--round-trips 300] [--pours 1]     (as root)

Round trip: the operator (root namespace) puts 100 B on ``roco/sim/disturb`` at the brain's
router; a process on the robot's host, authenticated as ag_ex, puts it back on
``roco/state/ag_ex``; mutual TLS between the routers, access control on. Pours: ``ROCO_REALTIME=0``
(the simulation as fast as it runs), the wall time from the command to a_hi's final report.
"""

from __future__ import annotations

import argparse
import os
import queue
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from services.hosts.fleet import TwoHosts
from services.hosts.link import Shaping
from services.hosts.netns import netns_exec, unavailable
from services.runtime.run_folder import new_run_dir
from services.runtime.session import open_client
from shared.settings import Settings

SHAPED = Shaping(20, 5, 1)
PLAIN = Shaping(0, 0, 0)
ECHO = (
    "import sys\nfrom services.runtime.session import open_client\n"
    "s = open_client('tls/127.0.0.1:7447', identity='ag_ex', wait_for_router=True)\n"
    "s.declare_subscriber('roco/sim/disturb', lambda x: s.put('roco/state/ag_ex', x.payload.to_bytes()))\n"
    "s.put('roco/state/ag_ex', b'ready')\nsys.stdin.read()\n"
)


def round_trips(root: Path, shaping: Shaping, n: int) -> list[float]:
    h = TwoHosts(new_run_dir(root), shaping, services=False)
    h.start()
    try:
        assert h.pair is not None and h.fleet is not None and h.fleet.security is not None
        env = {**os.environ, Settings.env_name("security"): str(h.fleet.security)}
        echo = subprocess.Popen([*netns_exec(h.pair.netns("robot")), sys.executable, "-c", ECHO], env=env,
                                stdin=subprocess.PIPE)  # fmt: skip
        s = open_client(h.endpoint)
        got: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        s.declare_subscriber("roco/state/ag_ex", lambda x: got.put(x.payload.to_bytes()))
        while True:  # until the echo's subscriber is known across the mesh
            s.put("roco/sim/disturb", b"warm")
            try:
                if got.get(timeout=1.0) == b"warm":
                    break
            except queue.Empty:
                continue
        times = []
        for i in range(n):
            payload = i.to_bytes(4, "big") * 25
            t0 = time.perf_counter()
            s.put("roco/sim/disturb", payload)
            while got.get(timeout=30) != payload:
                pass
            times.append(time.perf_counter() - t0)
        s.close()
        echo.terminate()
        echo.wait()
        return times
    finally:
        h.stop()


def pour_wall(root: Path, shaping: Shaping, partition_s: float | None) -> float:
    h = TwoHosts(
        new_run_dir(root), shaping, env={Settings.env_name("realtime"): "0", Settings.env_name("rerun"): "0"}
    )
    h.start()
    try:
        t0 = time.monotonic()
        cut: dict[str, Callable[[], object]] | None = None
        if partition_s:
            cut = {"take/reach": lambda: h.partition(partition_s)}
        report = h.say("pour the jar into the bowl", cut)
        wall = time.monotonic() - t0
        if not report.done_as_asked:
            raise SystemExit(f"bench_hosts: the pour failed: {report.text}")
        return wall
    finally:
        h.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--round-trips", type=int, default=300)
    parser.add_argument("--pours", type=int, default=1)
    args = parser.parse_args()
    why = unavailable()
    if why:
        print(f"bench_hosts: {why}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="bench_hosts-") as tmp:
        root = Path(tmp)
        for name, shaping in (("unshaped", PLAIN), ("20 ± 5 ms, 1 % loss", SHAPED)):
            t = sorted(round_trips(root, shaping, args.round_trips))
            p = [t[int(q * (len(t) - 1))] * 1e3 for q in (0.5, 0.9, 0.99)]
            print(f"round trip, link {name}: p50 {p[0]:.1f} ms, p90 {p[1]:.1f} ms, p99 {p[2]:.1f} ms, "
                  f"max {t[-1] * 1e3:.1f} ms ({len(t)} round trips)")  # fmt: skip
        for name, shaping, cut in (
            ("unshaped", PLAIN, None),
            ("shaped", SHAPED, None),
            ("shaped, 10 s partition", SHAPED, 10.0),
        ):
            walls = [pour_wall(root, shaping, cut) for _ in range(args.pours)]
            print(
                f"pour, link {name}: {statistics.median(walls):.1f} s wall ("
                + ", ".join(f"{w:.1f}" for w in walls)
                + ")"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
