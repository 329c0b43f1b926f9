"""Whether roco's fast tests survive the specification's growth: in a copy of this checkout,
agents are added the documented way (docs/spec.md: entries in the specification, ``roco spec
new-agent``, their handlers written; tests/support/checkout.py), and every test not marked
``slow`` runs there, by the copy's code (``pytest -m "not slow"``, on every CPU).

Two growths, each in its own copy:

- ``scratch``: the scratch agent a_sc, which asks a_km and tells the person through a_hi
  (tests/spec_check/walkthrough/scratch.py). The walk-through's own tests run too: they add the
  watcher to a specification that has grown already.
- ``both``: the walk-through's watcher a_wt, then a_sc. The tests marked ``walkthrough`` are
  left out (they would add the watcher again).

Prints, per growth, pytest's last line and each failed test; exit 0 when no test failed in
either, 1 when one did, 2 when an agent could not be added. README's test command runs the
fast part of this (tests/integration/test_new_agent.py); this runs all of it (about 10 min per
growth on a 2-core machine).

Usage: ``python scripts/check_growth.py [--only scratch|both] [--keep]``
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.checkout import Checkout, copy_checkout  # noqa: E402

GROWTHS = {"scratch": ("scratch",), "both": ("watcher", "scratch")}
"""Each growth: the agents added, in order."""
DESELECT = {"scratch": "not slow", "both": "not slow and not walkthrough"}
"""The tests each growth runs (a pytest ``-m`` expression)."""


def grow(copy: Checkout, agents: tuple[str, ...]) -> str | None:
    """Add ``agents`` to ``copy`` in order; what went wrong (one line), or None."""
    for agent in agents:
        done = copy.add_watcher() if agent == "watcher" else copy.add_scratch()
        if done.returncode != 0:
            return f"roco spec new-agent ({agent}) failed: {(done.stderr or done.stdout).strip()[-500:]}"
    for tool in ("check", "verify-code"):
        done = copy.roco("spec", tool)
        if done.returncode != 0:
            return f"roco spec {tool} failed: {done.stdout.strip()[-500:]}"
    return None


def run_tests(copy: Checkout, marks: str) -> tuple[bool, list[str]]:
    """The fast tests in ``copy``: whether they all passed, pytest's last line and the failures."""
    done = copy.run("-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "auto", "-m", marks, timeout=3600)
    lines = done.stdout.strip().splitlines()
    failed = [line for line in lines if line.startswith(("FAILED ", "ERROR "))]
    return done.returncode == 0, [*(lines[-1:] or ["(pytest printed nothing)"]), *failed]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(GROWTHS), help="one growth only")
    parser.add_argument("--keep", action="store_true", help="keep the copies (their paths are printed)")
    args = parser.parse_args()
    code = 0
    for name, agents in GROWTHS.items():
        if args.only and name != args.only:
            continue
        folder = Path(tempfile.mkdtemp(prefix=f"roco-growth-{name}-"))
        try:
            copy_checkout(folder)
            copy = Checkout(folder)
            wrong = grow(copy, agents)
            if wrong is not None:
                print(f"check_growth: {name}: {wrong}")
                return 2
            ok, said = run_tests(copy, DESELECT[name])
            print(f"check_growth: {name} ({' then '.join(agents)} added): {said[0]}")
            for line in said[1:]:
                print(f"  {line}")
            code = code or (0 if ok else 1)
        finally:
            if args.keep:
                print(f"check_growth: {name}: the copy is {folder}")
            else:
                shutil.rmtree(folder, ignore_errors=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
