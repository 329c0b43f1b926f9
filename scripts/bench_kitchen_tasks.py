"""Robustness of the kitchen tasks around the pour (velma/scenario_kitchen.py) over N seeds, the
robot alone on the threaded executor (no agents), the jar and bowl poses randomised as in
scripts/bench_pour_seeds.py (``--pose-seed`` = seed; ±2 cm, ±10°).

Tasks: ``interrupted`` (take jar and bowl out, bowl to the table; then "bring the cup to the
table": jar set down on the table, cup to the table, jar grasped again, pour) and ``tidy``
(jar and bowl out, bowl to the table; then jar and bowl back in the cabinet).

Printed per seed: the outcome, the spheres in the jar after it was set down and in the bowl
after the pour (interrupted), where jar and bowl ended (tidy), simulated and wall time.

Usage: ``python scripts/bench_kitchen_tasks.py [--task interrupted|tidy] [--seeds 3] [--first 1]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from shared.fipa_codec.languages.l_ex import CommandResult  # noqa: E402
from shared.fipa_codec.languages.l_sd import Observation  # noqa: E402
from velma import scenario_kitchen as sk  # noqa: E402
from velma.executor import Executor  # noqa: E402


def _where(obs: Observation, name: str) -> str:
    o = next(o for o in obs.objects if o.name == name)
    x, y, z = o.pose.position
    return f"{name} ({x:.3f}, {y:.3f}, {z:.3f})"


def run(task: str, seed: int) -> str:
    """One run; a Markdown table row."""
    ex = Executor(realtime=False, seed=seed, pose_seed=seed)
    ex.start()
    t0 = time.time()
    try:
        runner = sk.run_interrupted_pour if task == "interrupted" else sk.run_tidy_up
        commands, results = runner(ex.submit)
    finally:
        ex.stop()
    wall = time.time() - t0
    failed = next((r for r in results if isinstance(r, CommandResult) and not r.ok), None)
    obs = [r for r in results if isinstance(r, Observation)]
    final = obs[-1]
    if task == "interrupted":
        jar_down = obs[2] if len(obs) > 2 else None
        in_jar = sk.particles_in(jar_down, "jar") if jar_down is not None else None
        in_bowl = sk.particles_in(final, "bowl")
        detail = f"jar set down holding {in_jar}; bowl {in_bowl}/{final.total_particles}"
        ok = failed is None and in_bowl >= 0.9 * final.total_particles
    else:
        detail = f"{_where(final, 'jar')}, {_where(final, 'bowl')}"
        ok = failed is None
    if failed is not None:
        detail = f"{failed.command} failed: {failed.reason}; {detail}"
    stamp = final.stamp if len(results) == len(commands) else float("nan")
    return f"| {seed} | {'yes' if ok else 'NO'} | {detail} | {stamp:.1f} | {wall:.0f} |"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", choices=("interrupted", "tidy"), default="interrupted")
    ap.add_argument("--seeds", type=int, default=3, help="how many seeds")
    ap.add_argument("--first", type=int, default=1, help="first seed")
    args = ap.parse_args()
    print(f"# Kitchen task '{args.task}', seeds {args.first}..{args.first + args.seeds - 1}\n")
    print(f"Machine: {benchlib.machine(('mujoco', 'pin'))}\n")
    print("| seed | success | detail | sim s | wall s |")
    print("|---|---|---|---|---|")
    for seed in range(args.first, args.first + args.seeds):
        print(run(args.task, seed), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
