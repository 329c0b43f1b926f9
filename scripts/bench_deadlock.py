"""How long ``roco spec deadlock`` takes on the shipped specification: ``analyse`` (services/
spec_check/deadlock.py: every protocol explored as two role automata over FIFO queues, and the
agents' wait-for graph) timed in this process with ``time.perf_counter``, after one warm-up run;
printed with the product states explored. Target: well under 0.5 s a run.

Usage: ``python scripts/bench_deadlock.py [--repeats N]`` (default 20).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.spec.model import DEFAULT_SPEC  # noqa: E402
from services.spec_check.deadlock import analyse  # noqa: E402

TARGET_S = 0.5
"""A run of the analysis on the shipped specification takes less than this (exit 1 if not)."""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--repeats", type=int, default=20, help="timed runs after one warm-up run")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats is at least 1")
    result = analyse(DEFAULT_SPEC)  # warm-up: imports, the specification's first parse
    took = []
    for _ in range(args.repeats):
        began = time.perf_counter()
        analyse(DEFAULT_SPEC)
        took.append(time.perf_counter() - began)
    states = sum(p.states for p in result.protocols)
    transitions = sum(p.transitions for p in result.protocols)
    print(f"# roco spec deadlock on {DEFAULT_SPEC.relative_to(ROOT)} ({time.strftime('%Y-%m-%d')})")
    print(f"Machine: {benchlib.machine()}")
    print(f"{len(result.protocols)} protocols, {states} product states, {transitions} transitions explored")
    print(
        f"{args.repeats} runs: min {min(took) * 1e3:.1f} ms, median {statistics.median(took) * 1e3:.1f} ms, "
        f"max {max(took) * 1e3:.1f} ms (target < {TARGET_S * 1e3:.0f} ms)"
    )
    return 0 if max(took) < TARGET_S else 1


if __name__ == "__main__":
    sys.exit(main())
