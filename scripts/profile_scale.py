"""Where the CPU goes when many agent processes do round trips at once (issue 20, part 8).

For each N given, N synthetic agents (N/2 pairs, services/bench/synthetic.py) on one router on a
free loopback port, as ``roco bench``'s scale part starts them; 100 round trips per pair to warm
up, then ``--n`` round trips per pair, every pair at once. The CPU time of every thread of every
process (``/proc/<pid>/task/<tid>/stat``: user and system clock ticks) is read before and after;
printed per round trip, summed by role (initiators, participants, router) and thread name
(``python``: the agent's Python threads, its own (the process's main thread) apart from the
receiving one and the benchmark's command reader; ``rx-*``, ``tx-*``,
``app-*``, ``acc-*``, ``net-*``: Zenoh's runtime pools). Threads under 3 µs a round trip are
left out of the table, not of the total.

Usage: ``python scripts/profile_scale.py [--n 500] [N ...]`` (default N: 10 100)
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

TICKS_S = os.sysconf("SC_CLK_TCK")

ThreadTimes = dict[int, tuple[str, int, int]]
"""Thread id → (name, user ticks, system ticks)."""


def thread_times(pid: int) -> ThreadTimes:
    """Every thread of process ``pid`` with its CPU time so far (clock ticks)."""
    out: ThreadTimes = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            comm = (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        out[int(task.name)] = (comm, int(fields[11]), int(fields[12]))
    return out


def role(child: str) -> str:
    if child == "router":
        return "router"
    return "initiators" if child.startswith("b_ini") else "participants"


def profile(n_agents: int, n_rt: int) -> None:
    from services.bench.messaging import measure_all_pairs, testbed
    from services.bench.synthetic import WARMUP, pair_names

    pairs = max(1, n_agents // 2)
    names = [name for k in range(pairs) for name in pair_names(k)]
    with testbed(pairs, names, []) as bed:
        measure_all_pairs(bed, pairs, 100, 200)
        pids = {name: c.process.pid for name, c in bed.children.items() if c.process.pid is not None}
        assert bed.fleet is not None
        pids["router"] = bed.fleet.processes["router"].pid
        before = {name: thread_times(pid) for name, pid in pids.items()}
        figures = measure_all_pairs(bed, pairs, n_rt, 200)
        after = {name: thread_times(pid) for name, pid in pids.items()}
    round_trips = pairs * (n_rt + WARMUP)
    summed: dict[tuple[str, str], list[int]] = {}
    for name in pids:
        for tid, (comm, user, system) in after[name].items():
            _, user0, system0 = before[name].get(tid, (comm, 0, 0))
            if comm == "python" and name != "router":  # the main thread runs the agent's own loop
                comm = "python (agent's thread)" if tid == pids[name] else "python (receiving, commands)"
            got = summed.setdefault((role(name), comm), [0, 0])
            got[0] += user - user0
            got[1] += system - system0

    def us(ticks: int) -> float:
        return ticks / TICKS_S / round_trips * 1e6

    rate, steady = figures.round_trips_per_s, figures.steady_per_s
    print(f"\n## {len(names)} agents: {rate:,.0f} round trips/s (steady {steady:,.0f})")
    print("\n| processes | thread | user µs / round trip | system µs / round trip |\n|---|---|---|---|")
    total = 0.0
    for (who, comm), (user, system) in sorted(summed.items(), key=lambda kv: -sum(kv[1])):
        total += us(user) + us(system)
        if us(user) + us(system) >= 3:
            print(f"| {who} | {comm} | {us(user):.0f} | {us(system):.0f} |")
    print(f"\nall threads: {total:.0f} µs of CPU per round trip")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("agents", type=int, nargs="*", default=[10, 100], help="agent process counts")
    ap.add_argument("--n", type=int, default=500, help="round trips per pair, every pair at once")
    args = ap.parse_args()
    load = " / ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"# load average {load}; {args.n} round trips per pair")
    for n in args.agents:
        profile(n, args.n)
    return 0


if __name__ == "__main__":
    sys.exit(main())
