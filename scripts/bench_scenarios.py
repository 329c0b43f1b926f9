"""Every scenario of the library (services/scenario/library), run as a user runs it
(``roco scenario NAME --quiet``: router, recorder, one process per agent, MuJoCo not paced),
printed as a table: outcome as expected or not, wall time (none for a run not as expected: it
did not do the scenario's work), communicates, commands' outcomes.

Usage: ``python scripts/bench_scenarios.py [NAME ...]`` (default: every scenario of the library;
a name the library does not have is refused, exit 2).
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

from services.scenario.model import library  # noqa: E402


def main() -> int:
    known = library()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("names", nargs="*", metavar="NAME", help=f"scenarios to run (of: {', '.join(known)})")
    args = parser.parse_args()
    unknown = [n for n in args.names if n not in known]
    if unknown:
        parser.error(f"no scenario {unknown[0]!r} in the library (roco scenario --list)")
    names = args.names or list(known)
    print(f"# roco scenario, each once ({time.strftime('%Y-%m-%d')}, not paced)")
    print(f"Machine: {benchlib.machine(('mujoco', 'pin', 'eclipse-zenoh'))}")
    print()
    print("| scenario | as expected | wall (s) | communicates | outcomes |")
    print("|---|---|---|---|---|")
    failures = 0
    for name in names:
        with tempfile.TemporaryDirectory() as runs:
            t0 = time.monotonic()
            proc = subprocess.run(
                [sys.executable, "-m", "services.cli", "scenario", name, "--runs-dir", runs, "--quiet"],
                capture_output=True,
                text=True,
                cwd=ROOT,
                timeout=1800,
            )
            wall = time.monotonic() - t0
        out = proc.stdout + proc.stderr
        count = re.search(r"(\d+) communicates", out)
        outcomes = re.findall(r"→ (\w[\w-]*):", out)
        failures += proc.returncode != 0
        took = f"{wall:.1f}" if proc.returncode == 0 else "–"  # not as expected: not the scenario's time
        print(
            f"| {name} | {'yes' if proc.returncode == 0 else 'NO'} | {took} | "
            f"{count.group(1) if count else '?'} | {', '.join(outcomes)} |"
        )
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
