"""Functions whose cyclomatic complexity is 11 or more (radon's grade C and worse: "a state
machine hidden in branches"), per thousand lines of services/ and velma/.

Counts every function, method and nested function (radon ``cc_visit``; a class's own figure,
the mean of its methods, is not a function); lines are radon's LOC of the same files. Prints
the figure, the goal (at most ``--goal`` per thousand lines, 2 by default) and the functions,
worst first (``--top N``; 0: all). Exit 0 when the goal is met, 1 when not.

Usage: ``python scripts/check_complexity.py [--top 20] [--goal 2]``
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from radon.complexity import cc_visit
from radon.raw import analyze
from radon.visitors import Class, Function

ROOT = Path(__file__).resolve().parents[1]
TREES = ("services", "velma")
THRESHOLD = 11
"""radon's grade C begins here."""


@dataclass(frozen=True)
class Complex:
    """One function of complexity ≥ ``THRESHOLD``: where it is and its figure."""

    path: str
    line: int
    name: str
    complexity: int


def _functions(blocks: list[Function | Class]) -> list[Function]:
    """Every function of radon's blocks (methods are among them, with their class's name), and
    the functions nested in them."""
    out: list[Function] = []
    for block in blocks:
        if isinstance(block, Function):
            out.append(block)
            out += _functions(list(block.closures))
    return out


def survey(root: Path = ROOT) -> tuple[list[Complex], int]:
    """The functions of complexity ≥ ``THRESHOLD`` under ``root``'s trees, worst first, and
    the lines of code read."""
    found: list[Complex] = []
    lines = 0
    for tree in TREES:
        for path in sorted((root / tree).rglob("*.py")):
            code = path.read_text()
            lines += analyze(code).loc
            rel = path.relative_to(root).as_posix()
            for f in _functions(cc_visit(code)):
                if f.complexity >= THRESHOLD:
                    name = f"{f.classname}.{f.name}" if f.classname else f.name
                    found.append(Complex(rel, f.lineno, name, f.complexity))
    found.sort(key=lambda c: (-c.complexity, c.path, c.line))
    return found, lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=20, help="functions to list, worst first (0: all)")
    parser.add_argument("--goal", type=float, default=2.0, help="at most this many per thousand lines")
    args = parser.parse_args(argv)
    found, lines = survey()
    per_kloc = 1000.0 * len(found) / max(lines, 1)
    trees = " and ".join(f"{t}/" for t in TREES)
    print(
        f"{len(found)} functions of complexity ≥ {THRESHOLD} in {lines:,} lines of {trees}: "
        f"{per_kloc:.2f} per thousand lines (goal ≤ {args.goal:g})"
    )
    for c in found[: args.top or None]:
        print(f"{c.complexity:4d}  {c.path}:{c.line}  {c.name}")
    return 0 if per_kloc <= args.goal else 1


if __name__ == "__main__":
    sys.exit(main())
