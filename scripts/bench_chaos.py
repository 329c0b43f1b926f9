"""Chaos runs as a user runs them (``roco chaos --seed S --quiet``: router, recorder, one
process per agent, MuJoCo not paced; each agent killed, paused or restarted once during the
pour, services/scenario/chaos.py), one per seed, printed as a table: the faults drawn, the
verdict's four answers, wall time.

Usage: ``python scripts/bench_chaos.py [--hosts] [SEED ...]`` (default seeds 1 2 3 4 5; with
``--hosts`` each run is ``roco chaos --hosts``: on two hosts of this machine, both routers and
the link faulted too; root)
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.scenario.chaos import CHAOS_FILE, chaos_scenario  # noqa: E402

ANSWERS = ("task done", "no command lost", "nothing executed twice", "no object dropped")


def main() -> int:
    parser = argparse.ArgumentParser(description="roco chaos runs, one per seed, as a table")
    parser.add_argument("seeds", nargs="*", type=int, default=[1, 2, 3, 4, 5], metavar="SEED")
    parser.add_argument("--hosts", action="store_true", help="roco chaos --hosts (two hosts; root)")
    args = parser.parse_args()
    seeds, hosts = args.seeds, ["--hosts"] if args.hosts else []
    title = "roco chaos --hosts" if args.hosts else "roco chaos"
    print(f"# {title}, one run per seed ({time.strftime('%Y-%m-%d')}, not paced)")
    print(f"Machine: {benchlib.machine(('mujoco', 'pin', 'eclipse-zenoh'))}")
    print()
    print("| seed | faults (service kind) | " + " | ".join(ANSWERS) + " | wall (s) |")
    print("|---|---|" + "---|" * len(ANSWERS) + "---|")
    failures = 0
    for seed in seeds:
        faults = ", ".join(
            f"{s.fault.service} {s.fault.kind}"
            for s in chaos_scenario(seed, hosts=args.hosts).steps
            if s.fault
        )
        with tempfile.TemporaryDirectory() as runs:
            t0 = time.monotonic()
            proc = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "services.cli",
                    "chaos",
                    *hosts,
                    "--seed",
                    str(seed),
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
        print(f"| {seed} | {faults} | " + " | ".join(answers) + f" | {wall:.0f} |")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
