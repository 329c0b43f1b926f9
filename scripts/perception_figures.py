"""Perception figures of fleet runs: ag_ex's perception logs (``ag_ex_perception.jsonl``,
velma/executor/perception_log.py: each camera Observation's objects beside the simulation's
truth) of every run folder under the given folders, summed up.

Printed: per object, how often it was asked for and seen and the position error against the
truth (mm, p50 / p95 / max); the content count of the bowl at each run's last observation of
it (the pour's content check) against the truth, with the spheres seen and those inferred
behind its near wall; the wall time of an Observe (render, noise, localisation, content; ms,
p50 / p95 / max, the first of each run apart: it makes the renderer).

Usage: ``python scripts/perception_figures.py RUNS_DIR [RUNS_DIR ...]`` (e.g. the folder
``scripts/bench_pour_seeds.py --mode fleet`` prints as "Run folders").
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

LOG = "ag_ex_perception.jsonl"


def percentiles(values: list[float]) -> str:
    """ "p50 / p95 / max" of ``values`` ("—" when empty)."""
    if not values:
        return "—"
    a = np.asarray(values, dtype=np.float64)
    return f"{np.percentile(a, 50):.1f} / {np.percentile(a, 95):.1f} / {a.max():.1f}"


def main(argv: list[str] | None = None) -> int:
    """Print the figures; 1 (with one line on stderr) when no run folder has a perception log."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="folders holding run folders (or run folders)")
    args = ap.parse_args(argv)
    logs = sorted({p for d in args.runs for p in [*d.glob(LOG), *d.glob(f"*/{LOG}")]})
    if not logs:
        print(f"perception_figures: no {LOG} under {', '.join(map(str, args.runs))}", file=sys.stderr)
        return 1
    errors: dict[str, list[float]] = {}
    asked: dict[str, int] = {}
    seen: dict[str, int] = {}
    first_ms: list[float] = []
    later_ms: list[float] = []
    checks: list[tuple[int, int, int, int]] = []  # count, truth, visible, hidden
    for log in logs:
        records = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
        stamps: list[float] = []
        for r in records:
            name = r["object"]
            asked[name] = asked.get(name, 0) + 1
            if r["seen"]:
                seen[name] = seen.get(name, 0) + 1
                errors.setdefault(name, []).append(float(r["error_mm"]))
            if r["sim_time"] not in stamps:
                stamps.append(r["sim_time"])
                (first_ms if len(stamps) == 1 else later_ms).append(float(r["observe_ms"]))
        bowl = [r for r in records if r["object"] == "bowl" and r["seen"] and r["content"] is not None]
        if bowl:
            last = bowl[-1]
            visible = last["visible"] or 0
            # the count is the spheres seen plus those inferred (logs before "hidden" lack it)
            checks.append((last["content"], last["content_truth"], visible, last["content"] - visible))
    print(f"{len(logs)} runs ({', '.join(str(d) for d in args.runs)})")
    print("object  asked  seen  position error mm (p50 / p95 / max)")
    for name in sorted(asked):
        print(f"{name:6s}  {asked[name]:5d}  {seen.get(name, 0):4d}  {percentiles(errors.get(name, []))}")
    every = [e for v in errors.values() for e in v]
    print(f"all     {sum(asked.values()):5d}  {sum(seen.values()):4d}  {percentiles(every)}")
    if checks:
        err = [c - t for c, t, _, _ in checks]
        print(
            f"bowl content at the last observation (the content check), {len(checks)} runs: "
            f"count − truth from {min(err):+d} to {max(err):+d}, mean {np.mean(err):+.2f}; "
            f"truth {min(t for _, t, _, _ in checks)}–{max(t for _, t, _, _ in checks)}; "
            f"seen {min(v for _, _, v, _ in checks)}–{max(v for _, _, v, _ in checks)}, "
            f"inferred behind the wall {min(h for *_, h in checks)}–{max(h for *_, h in checks)}"
        )
    print(
        f"Observe wall time ms (p50 / p95 / max): first of a run {percentiles(first_ms)}; "
        f"later {percentiles(later_ms)}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
