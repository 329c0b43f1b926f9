"""Where one pair's stream spends its CPU, in batches and with one put per communicate
(docs/benchmarks.md, "One put for what one step sends to one receiver").

The benchmark's synthetic pair (``b_ini0``/``b_par0``, services/bench/synthetic.py) on a router
of its own on a free loopback port, started as ``roco bench`` starts them (multiprocessing
spawn). After one warm-up stream, ``--repeat`` alternations of two streams of ``--n`` informs
(200 B of content, 256 per step, one fipa-subscribe conversation): first with what a step sends
to its receiver in batches (shared/fipa_codec/batch.py), then one put per communicate
(``Engine.batch_puts`` False). For each stream: the rate the initiator measured (as
services/bench/messaging.py's ``Throughput`` counts it), communicates lost, and the CPU time of
each process per communicate (``/proc/<pid>/task/<tid>/stat``: user + system ticks of every
thread, scripts/benchlib.py), the agent's own thread (the process's main thread) apart.

Usage: ``python scripts/profile_stream.py [--n 20000] [--repeat 3]``
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


Reading = dict[str, dict[int, tuple[int, int]]]
"""Process → thread id → (user, system) clock ticks used so far."""


def per_communicate(before: Reading, after: Reading, process: str, n: int, only: int | None = None) -> float:
    """CPU time (µs) per communicate that ``process``'s threads (or only thread ``only``) used
    between two readings, over ``n`` communicates."""
    threads = set(after[process]) if only is None else {only}
    old = before[process]
    ticks = sum(sum(after[process][t]) - sum(old.get(t, (0, 0))) for t in threads if t in after[process])
    return ticks / TICKS_S * 1e6 / n


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20000, help="informs per stream")
    parser.add_argument("--repeat", type=int, default=3, help="alternations of the two streams")
    args = parser.parse_args()

    import benchlib  # scripts/benchlib.py, beside this file

    from services.bench.messaging import (
        Exchange,
        SetupError,
        Throughput,
        _answer,
        check_exchange,
        counters_of,
        testbed,
    )
    from services.bench.synthetic import pair_names

    def reading(pids: dict[str, int]) -> Reading:
        return {
            k: {t: (u.user, u.system) for t, u in benchlib.thread_use(p).items()} for k, p in pids.items()
        }

    print(f"# {benchlib.machine(('eclipse-zenoh', 'msgspec'))}; load {os.getloadavg()[0]:.2f}")
    names = pair_names(0)
    with testbed(1, names, []) as bed:
        assert bed.fleet is not None
        ini, par = bed.children[names[0]], bed.children[names[1]]
        assert ini.process.pid is not None and par.process.pid is not None
        pids = {
            "receiver": ini.process.pid,
            "sender": par.process.pid,
            "router": bed.fleet.processes["router"].pid,
        }
        _answer(ini, ("stream", 2000, 200), 120)  # warm-up
        print(
            "\n| stream | /s | lost | receiver µs CPU per communicate (its agent's thread) "
            "| sender (its agent's thread) | router |\n|---|---|---|---|---|---|"
        )
        for _ in range(args.repeat):
            for batched in (True, False):
                counted = counters_of(ini), counters_of(par)
                before = reading(pids)
                got = _answer(ini, ("stream", args.n, 200, batched), 120)
                after = reading(pids)
                want = Exchange({"subscribe": 1}, {"agree": 1, "inform": args.n})
                try:
                    check_exchange(counters_of(ini) - counted[0], counters_of(par) - counted[1], want, names)
                except SetupError as exc:
                    print(f"roco: profile_stream: {exc}", file=sys.stderr)
                    return 1
                runs = Throughput()
                runs.add(got, args.n)
                rate = runs.rates[0]
                cells = [
                    f"{per_communicate(before, after, k, args.n):.1f}"
                    + (
                        f" ({per_communicate(before, after, k, args.n, pids[k]):.1f})"
                        if k != "router"
                        else ""
                    )
                    for k in ("receiver", "sender", "router")
                ]
                kind = "in batches" if batched else "one put per communicate"
                print(f"| {kind} | {rate:,.0f} | {args.n - got['count']} | {' | '.join(cells)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
