"""Chaos runs as a user runs them (``roco chaos --seed S --quiet``: router, recorder, one
process per agent, MuJoCo not paced unless ``--realtime``; each agent killed, paused or
restarted once during the pour, services/scenario/chaos.py), one per seed, printed as a
table: the faults drawn, how many fell during the command, the verdict's six answers, wall
time (none when the verdict failed).

Usage: ``python scripts/bench_chaos.py [--hosts] [--realtime] [--kinds K,…] [--count N]
[--load N] [--runs-dir DIR] [SEED ...]`` (default seeds 1 2 3 4 5; with ``--hosts`` each run is ``roco chaos
--hosts``: on two hosts of this machine, both routers and the link faulted too; root;
``--realtime`` paces the pour to wall time, so that more of the faults fall during it;
``--kinds``, ``--count`` and ``--load`` (N processes keeping a core busy each) go to ``roco
chaos``; ``--runs-dir`` keeps each run's folder there). The last line says how many runs were
done: every answer yes.
The fleet's environment is this one's: ``ROCO_WORLD=loop`` runs the kitchen inside ag_ex's
loop instead of a world process of its own (docs/executor.md).
"""

from __future__ import annotations

import argparse
import contextlib
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.scenario.chaos import CHAOS_FILE, QUESTIONS, chaos_scenario  # noqa: E402
from shared.settings import Settings  # noqa: E402

ANSWERS = QUESTIONS


def main() -> int:
    parser = argparse.ArgumentParser(description="roco chaos runs, one per seed, as a table")
    parser.add_argument("seeds", nargs="*", type=int, default=[1, 2, 3, 4, 5], metavar="SEED")
    parser.add_argument("--hosts", action="store_true", help="roco chaos --hosts (two hosts; root)")
    parser.add_argument(
        "--realtime",
        action="store_true",
        help="pace the simulation to wall time (more faults fall in the pour)",
    )
    parser.add_argument("--kinds", default="kill,pause,restart", help="fault kinds (roco chaos --kinds)")
    parser.add_argument("--count", type=int, default=None, help="random faults (roco chaos --count)")
    parser.add_argument(
        "--load", type=int, default=0, help="busy processes beside the fleet (roco chaos --load)"
    )
    parser.add_argument(
        "--runs-dir",
        type=Path,
        default=None,
        help="keep the run folders here (default: removed after each run)",
    )
    args = parser.parse_args()
    seeds, hosts = args.seeds, ["--hosts"] if args.hosts else []
    title = "roco chaos --hosts" if args.hosts else "roco chaos"
    paced = "paced to wall time" if args.realtime else "not paced"
    kinds = tuple(args.kinds.split(","))
    faulted = f"--kinds {args.kinds}" + (f" --count {args.count}" if args.count else "")
    faulted += f" --load {args.load}" if args.load else ""
    world = f"{Settings.env_name('world')}={Settings.from_env(only=('world',)).world}"
    print(f"# {title} {faulted}, one run per seed ({time.strftime('%Y-%m-%d')}, {paced}, {world})")
    print(f"Machine: {benchlib.machine(('mujoco', 'pin', 'eclipse-zenoh'))}")
    print()
    print("| seed | faults (service kind) | in the pour | " + " | ".join(ANSWERS) + " | wall (s) |")
    print("|---|---|---|" + "---|" * len(ANSWERS) + "---|")
    failures = 0
    for seed in seeds:
        faults = ", ".join(
            f"{s.fault.service} {s.fault.kind}"
            for s in chaos_scenario(seed, hosts=args.hosts, kinds=kinds, count=args.count).steps
            if s.fault
        )
        with _runs_dir(args.runs_dir, seed) as runs:
            t0 = time.monotonic()
            proc = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "services.cli",
                    "chaos",
                    *hosts,
                    *(["--realtime"] if args.realtime else []),
                    "--seed",
                    str(seed),
                    "--kinds",
                    args.kinds,
                    *(["--count", str(args.count)] if args.count else []),
                    "--load",
                    str(args.load),
                    "--runs-dir",
                    runs,
                    "--quiet",
                ],
                capture_output=True,
                text=True,
                cwd=ROOT,
                timeout=1800,
            )
            wall = time.monotonic() - t0
            found = list(Path(runs).glob(f"*/{CHAOS_FILE}"))
            text = found[0].read_text() if found else ""
        answers = []
        for question in ANSWERS:
            m = re.search(rf"\| {question} \| (\S+)", text)
            answers.append(m.group(1).strip("*") if m else "?")
        failures += proc.returncode != 0
        during = re.search(r"\| faults during the command \| (\d+ of \d+) \|", text)
        in_pour = during.group(1) if during else "?"
        took = f"{wall:.0f}" if proc.returncode == 0 else "–"  # a failed verdict: no run's time
        print(f"| {seed} | {faults} | {in_pour} | " + " | ".join(answers) + f" | {took} |")
    print()
    print(f"done: {len(seeds) - failures} of {len(seeds)} runs (every answer yes)")
    return 1 if failures else 0


def _runs_dir(keep: Path | None, seed: int) -> contextlib.AbstractContextManager[str]:
    """Where one run's folder is made: a new folder in ``keep`` (kept), else a temporary one."""
    if keep is None:
        return tempfile.TemporaryDirectory()
    keep.mkdir(parents=True, exist_ok=True)
    return contextlib.nullcontext(tempfile.mkdtemp(dir=keep, prefix=f"seed{seed}-"))


if __name__ == "__main__":
    sys.exit(main())
