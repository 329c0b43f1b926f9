"""Where the CPU goes when many agent processes do round trips at once (``roco bench`` part 8;
docs/benchmarks.md, "Where the limit is").

For each N given, N synthetic agents (N/2 pairs, services/bench/synthetic.py) on one router on a
free loopback port, as ``roco bench``'s scale part starts them; 100 round trips per pair to warm
up, then ``--n`` round trips per pair, every pair at once. The CPU time of every thread of every
process (``/proc/<pid>/task/<tid>/stat``: user and system clock ticks) is read before and after;
printed per round trip with the threads' context switches (``/proc/<pid>/task/<tid>/status``),
summed by role (initiators, participants, router) and thread name
(``python``: the agent's Python threads, its own (the process's main thread) apart from the
receiving one and the benchmark's command reader; ``rx-*``, ``tx-*``,
``app-*``, ``acc-*``, ``net-*``: Zenoh's runtime pools). Threads under 3 µs a round trip are
left out of the table, not of the total. ``--idle S``: first, before any round trip, the CPU
and wake-ups of every thread while the agents wait for S seconds. ``--pin pair``: every thread
of pair k's two processes on core k mod 2; ``--pin ends``: the initiator on core k mod 2, the
participant on the other (``sched_setaffinity``; the router left free).

Usage: ``python scripts/profile_scale.py [--n 500] [--idle 10] [--pin pair|ends] [N ...]``
(default N: 10 100)
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

TICKS_S = os.sysconf("SC_CLK_TCK")

Use = dict[str, dict[int, Any]]
"""Process name → thread id → scripts/benchlib.py ``ThreadUse`` (name, user and system ticks,
voluntary and involuntary context switches)."""


def use_of(pids: dict[str, int]) -> Use:
    """What every thread of the processes ``pids`` has used so far."""
    import benchlib  # scripts/benchlib.py, beside this file

    return {name: benchlib.thread_use(pid) for name, pid in pids.items()}


def role(child: str) -> str:
    if child == "router":
        return "router"
    return "initiators" if child.startswith("b_ini") else "participants"


Summed = dict[tuple[str, str], list[int]]
"""(processes, thread name) → [user ticks, system ticks, voluntary, involuntary switches]."""


def summed(pids: dict[str, int], before: Use, after: Use) -> Summed:
    """What every thread used between ``before`` and ``after``, summed by role and name."""
    out: Summed = {}
    for name, pid in pids.items():
        for tid, (comm, *now) in after[name].items():
            then = tuple(before[name][tid][1:]) if tid in before[name] else (0, 0, 0, 0)
            if comm == "python" and name != "router":  # the main thread runs the agent's own loop
                comm = "python (agent's thread)" if tid == pid else "python (receiving, commands)"
            got = out.setdefault((role(name), comm), [0, 0, 0, 0])
            for i, (x, x0) in enumerate(zip(now, then, strict=True)):
                got[i] += x - x0
    return out


def idle(pids: dict[str, int], seconds: float) -> None:
    """CPU (% of one core) and wake-ups per second of every thread while nothing is asked."""
    before = use_of(pids)
    time.sleep(seconds)  # a measuring window, not a synchronisation
    after = use_of(pids)
    print(f"\nidle for {seconds:.0f} s:\n")
    print("| processes | thread | % of one core | wake-ups /s |\n|---|---|---|---|")
    total = 0.0
    for (who, comm), (user, system, vol, _) in sorted(
        summed(pids, before, after).items(), key=lambda kv: -sum(kv[1][:2])
    ):
        share = (user + system) / TICKS_S / seconds * 100
        total += share
        if share >= 0.1 or vol / seconds >= 1:
            print(f"| {who} | {comm} | {share:.1f} | {vol / seconds:,.0f} |")
    print(f"\nall threads: {total:.1f} % of one core")


def pin(pid: int, core: int) -> None:
    """Every thread of process ``pid`` on CPU ``core`` only (threads that ended meanwhile are
    passed over)."""
    for tid in os.listdir(f"/proc/{pid}/task"):
        with contextlib.suppress(OSError):
            os.sched_setaffinity(int(tid), {core})


def profile(n_agents: int, n_rt: int, idle_s: float, pinned: str | None = None) -> None:
    from services.bench.messaging import Exchange, check_exchange, counters_of, measure_all_pairs, testbed
    from services.bench.synthetic import WARMUP, pair_names

    pairs = max(1, n_agents // 2)
    names = [name for k in range(pairs) for name in pair_names(k)]
    with testbed(pairs, names, []) as bed:
        pids = {name: c.process.pid for name, c in bed.children.items() if c.process.pid is not None}
        assert bed.fleet is not None
        pids["router"] = bed.fleet.processes["router"].pid
        for k in range(pairs if pinned else 0):
            ini, par = pair_names(k)
            pin(pids[ini], k % 2)
            pin(pids[par], k % 2 if pinned == "pair" else 1 - k % 2)
        if idle_s > 0:
            print(f"\n## {len(names)} agents")
            idle(pids, idle_s)
        measure_all_pairs(bed, pairs, 100, 200)
        children = [tuple(bed.children[n] for n in pair_names(k)) for k in range(pairs)]
        counted = [(counters_of(i), counters_of(p)) for i, p in children]
        before = use_of(pids)
        figures = measure_all_pairs(bed, pairs, n_rt, 200)
        after = use_of(pids)
        want = Exchange({"request": WARMUP + n_rt}, {"inform": WARMUP + n_rt})
        for k, ((i, p), (bi, bp)) in enumerate(zip(children, counted, strict=True)):
            check_exchange(counters_of(i) - bi, counters_of(p) - bp, want, pair_names(k))
    round_trips = pairs * (n_rt + WARMUP)

    def us(ticks: int) -> float:
        return ticks / TICKS_S / round_trips * 1e6

    rate, steady = figures.round_trips_per_s, figures.steady_per_s
    print(f"\n## {len(names)} agents: {rate:,.0f} round trips/s (steady {steady:,.0f})")
    print(
        "\n| processes | thread | user µs / round trip | system µs / round trip "
        "| context switches / round trip (voluntary + involuntary) |\n|---|---|---|---|---|"
    )
    total = switches = 0.0
    for (who, comm), (user, system, vol, invol) in sorted(
        summed(pids, before, after).items(), key=lambda kv: -sum(kv[1][:2])
    ):
        total += us(user) + us(system)
        switches += (vol + invol) / round_trips
        if us(user) + us(system) >= 3 or (vol + invol) / round_trips >= 0.1:
            print(
                f"| {who} | {comm} | {us(user):.0f} | {us(system):.0f} "
                f"| {vol / round_trips:.2f} + {invol / round_trips:.2f} |"
            )
    print(f"\nall threads: {total:.0f} µs of CPU and {switches:.1f} context switches per round trip")


def main() -> int:
    """Profile each N (module docstring); exit 1 with one ``roco:`` line, and no figure for that
    N, when a pair's exchange was not the work timed (services/bench/messaging.py
    ``check_exchange``: a round trip missing, anything refused or not understood)."""
    from services.bench.messaging import SetupError

    try:
        return _main()
    except SetupError as exc:
        print(f"roco: profile_scale: {exc}", file=sys.stderr)
        return 1


def _main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("agents", type=int, nargs="*", default=[10, 100], help="agent process counts")
    ap.add_argument("--n", type=int, default=500, help="round trips per pair, every pair at once")
    ap.add_argument("--idle", type=float, default=0.0, help="first measure the idle agents for this long (s)")
    ap.add_argument("--pin", choices=("pair", "ends"), help="pin each pair's processes to cores")
    args = ap.parse_args()
    load = " / ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"# load average {load}; {args.n} round trips per pair")
    for n in args.agents:
        profile(n, args.n, args.idle, args.pin)
    return 0


if __name__ == "__main__":
    sys.exit(main())
