"""The goals of the figures measured by scripts rather than by ``roco bench`` parts (those are
services/bench/report.py's ``TARGET_*``), each stated once here.

Each is a bound and the side a figure must stay on; :meth:`Target.verdict` says met or missed.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Target:
    """A bound on a figure: at most ``limit`` (``at_most``) or at least ``limit``."""

    limit: float
    unit: str
    at_most: bool = True

    def met(self, value: float) -> bool:
        return value <= self.limit if self.at_most else value >= self.limit

    def text(self) -> str:
        """The bound as the docs write it, e.g. ``≤ 400 µs``."""
        return f"{'≤' if self.at_most else '≥'} {self.limit:g} {self.unit}".rstrip()

    def verdict(self, value: float) -> str:
        """``"met"`` or ``"missed"``."""
        return "met" if self.met(value) else "missed"


LOOP_WORK_P99 = Target(400.0, "µs")
"""ag_ex's 1 kHz loop in real time: each run's cycle work at p99 (scripts/bench_loop.py), at most
(docs/executor.md, the loop's goals)."""
CONTROLLER_P99 = Target(150.0, "µs")
"""Velma's two-arm controller alone, ``update(q, v)`` at p99 (scripts/bench_controller.py), at most."""
LOOP_OVERRUNS = Target(0.1, "%")
"""ag_ex's 1 kHz loop in real time: each run's share of cycles that overran, at most."""
