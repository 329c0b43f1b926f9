"""Module docstrings are contracts, not essays: across every ``.py`` under ``services/``,
``shared/`` and ``velma/`` the median module docstring is at most ``MEDIAN`` lines and none
is over ``LONGEST``. Measurements and why-history belong in docs/ (or git), not in a module.

A line is a line of ``ast.get_docstring`` (cleaned); a module without one counts 0.
``PENDING`` names modules still over ``LONGEST`` that are being restructured elsewhere: each
counts as ``MEDIAN`` lines, and a ``PENDING`` module that is no longer over ``LONGEST`` fails
the test, so the set only shrinks.
"""

from __future__ import annotations

import ast
import statistics
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("services", "shared", "velma")
MEDIAN = 15
LONGEST = 60
PENDING: frozenset[str] = frozenset()
"""Modules (repo-relative) whose docstring is over ``LONGEST`` lines, left for a later pass."""


def measure(root: Path) -> dict[str, int]:
    """Lines of each module docstring under ``root``'s scanned packages, keyed by the
    repo-relative path (``/``-separated); 0 for a module without one. Raises ``SyntaxError``
    for a module that does not parse."""
    lengths: dict[str, int] = {}
    for package in SCANNED:
        for path in sorted((root / package).rglob("*.py")):
            doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")), clean=True)
            lengths[path.relative_to(root).as_posix()] = len(doc.splitlines()) if doc else 0
    return lengths


def offences(lengths: dict[str, int], pending: frozenset[str] = PENDING) -> list[str]:
    """Why ``lengths`` breaks the rule, one line each (empty when it keeps it): modules over
    ``LONGEST`` (worst first), a median over ``MEDIAN`` (with the twenty longest), and
    ``pending`` modules that no longer exceed ``LONGEST`` or no longer exist."""
    found: list[str] = []
    counted = {path: MEDIAN if path in pending else n for path, n in lengths.items()}
    worst = sorted(((n, path) for path, n in counted.items()), reverse=True)
    found += [f"{path}: {n} lines > {LONGEST}" for n, path in worst if n > LONGEST]
    median = statistics.median(counted.values()) if counted else 0
    if median > MEDIAN:
        found.append(
            f"median {median} lines > {MEDIAN}; longest: " + ", ".join(f"{p} {n}" for n, p in worst[:20])
        )
    found += [
        f"{path}: PENDING but {lengths[path]} lines, drop it from PENDING"
        for path in sorted(pending)
        if lengths.get(path, 0) <= LONGEST
    ]
    return found


def test_module_docstrings_are_short() -> None:
    found = offences(measure(ROOT))
    assert not found, "\n".join(found)


def _tree(tmp_path: Path, docs: dict[str, int]) -> Path:
    for package in SCANNED:
        (tmp_path / package).mkdir()
    for relative, n in docs.items():
        body = "\n".join(f"line {i}" for i in range(n))
        (tmp_path / relative).write_text(f'"""{body}"""\n' if n else "x = 1\n", encoding="utf-8")
    return tmp_path


def test_the_rule_catches_an_essay_a_long_median_and_a_stale_pending(tmp_path: Path) -> None:
    lengths = measure(_tree(tmp_path, {"services/a.py": 61, "shared/b.py": 3, "velma/c.py": 0}))
    assert lengths == {"services/a.py": 61, "shared/b.py": 3, "velma/c.py": 0}
    assert offences(lengths, frozenset()) == ["services/a.py: 61 lines > 60"]
    assert offences(lengths, frozenset({"services/a.py"})) == []
    assert offences({"a.py": 16, "b.py": 16, "c.py": 1}, frozenset())[0].startswith("median 16 lines > 15")
    assert offences(lengths, frozenset({"services/a.py", "shared/b.py"})) == [
        "shared/b.py: PENDING but 3 lines, drop it from PENDING"
    ]
