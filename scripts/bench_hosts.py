"""Figures of the fleet on two hosts (docs/deploy.md, "Two hosts on one machine"): the round trip
across the link, the pour's wall time with and without shaping, and what a 10 s partition costs;
with ``--put-overhead``, only the bytes one put adds on the routers' link.

    .venv/bin/python scripts/bench_hosts.py [--round-trips 300] [--pours 1]     (as root)
    .venv/bin/python scripts/bench_hosts.py --put-overhead                      (as root)

Round trip: the operator (root namespace) puts 100 B on ``roco/sim/disturb`` at the brain's
router; a process on the robot's host, authenticated as ag_ex, puts it back on
``roco/state/ag_ex``; mutual TLS between the routers, access control on. Pours: ``ROCO_REALTIME=0``
(the simulation as fast as it runs), the wall time from the command to a_hi's final report.

Put overhead (services/spec_check/placement.py ``PUT_OVERHEAD_B``): the two hosts with the
routers, the relay and the recorder only; a process on the robot's host, authenticated as ag_ex,
puts communicates of a fixed size through roco's transport (an advanced publisher on
``roco/fipa/C5/ag_ex/a_ta``, as ag_ex does), each alone, at a fixed rate; the recorder on the
brain subscribes as in a run. The relay counts the bytes the link carries robot → brain
(link_bytes.jsonl); the overhead per put is (bytes in the seconds of the puts − puts × size) /
puts.
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
PUTTER = (
    "import sys, time\nfrom services.runtime.transport import ZenohTransport\n"
    "from shared.fipa_codec import AgentIdentifier, Communicate, Performative, encode\n"
    "n, period, size = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])\n"
    "t = ZenohTransport(['tls/127.0.0.1:7447'], identity='ag_ex')\n"
    "def put(i):\n"
    "    c = Communicate(performative=Performative.INFORM, sender=AgentIdentifier('ag_ex'),\n"
    "                    receiver=(AgentIdentifier('a_ta'),), content=b'x' * size,\n"
    "                    protocol='fipa-request', conversation_id=f'c-{i:012d}')\n"
    "    payload = encode(c)\n    t0 = time.time()\n"
    "    t.publish('roco/fipa/C5/ag_ex/a_ta', payload)\n    return t0, len(payload)\n"
    "put(n)\ntime.sleep(3.0)  # the publisher declared, its declarations across\n"
    "for i in range(n):\n"
    "    print(*put(i), flush=True)\n    time.sleep(period)\n"
    "time.sleep(3.0)\n"
)
PUT_RUNS = ((100, 0.05, 400), (40, 0.5, 400), (100, 0.05, 2000))
"""(puts, seconds between them, content bytes) of each measurement of the put overhead."""


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


def put_overhead(root: Path) -> list[tuple[int, float, int, float]]:
    """(puts, period s, payload bytes, overhead B per put) of each of :data:`PUT_RUNS`."""
    from services.recorder.record import read_link_bytes

    h = TwoHosts(new_run_dir(root), PLAIN, services=False)
    h.start()
    try:
        assert h.pair is not None and h.fleet is not None and h.fleet.security is not None
        h.fleet.start_recorder()
        s = open_client(h.endpoint)
        h.fleet.wait_alive(s, ["recorder"], timeout=60)
        s.close()
        env = {**os.environ, Settings.env_name("security"): str(h.fleet.security)}
        done = []
        robot = netns_exec(h.pair.netns("robot"))
        for n, period, content in PUT_RUNS:
            cmd = [*robot, sys.executable, "-c", PUTTER, str(n), str(period), str(content)]
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            sent = [(float(t), int(size)) for t, size in (line.split() for line in out.stdout.splitlines())]
            done.append((n, period, sent))
        run_dir = h.run_dir
    finally:
        h.stop()  # the relay writes its last seconds as it stops
    seconds = read_link_bytes(run_dir)
    out_rows = []
    for n, period, sent in done:
        first, last = int(sent[0][0]), int(sent[-1][0]) + 1  # the second after the last: the delay
        carried = sum(x.up for x in seconds if first <= x.t <= last)
        size = sent[0][1]
        out_rows.append((n, period, size, (carried - n * size) / n))
    return out_rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--round-trips", type=int, default=300)
    parser.add_argument("--pours", type=int, default=1)
    parser.add_argument("--put-overhead", action="store_true", help="only the bytes one put adds on the link")
    args = parser.parse_args()
    why = unavailable()
    if why:
        print(f"bench_hosts: {why}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="bench_hosts-") as tmp:
        root = Path(tmp)
        if args.put_overhead:
            for n, period, size, overhead in put_overhead(root):
                print(f"put overhead: {n} puts of {size} B, one per {period:g} s: {overhead:.1f} B each")
            return 0
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
