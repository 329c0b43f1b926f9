"""The robot's clock beside the recorder's: the simulation time (robot time) of the moments
the report shows.

The traffic record stamps each communicate with the recorder's wall clock. In the fast
pacing of ``roco run`` the simulation runs faster than that (docs/viewer.md, "The report"),
so wall-clock durations do not compare with the paper's, which a real robot logged in real
time. Every answer of ag_ex on C5 carries the simulation time it ended at
(L_EX ``CommandResult.sim_time``, L_SD ``Observation.stamp``): those pairs (recorder time,
robot time) are the clock's marks, and a moment between two marks reads as the straight line
between them. Before the first mark or after the last, the robot's time is not known.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence

import msgspec

from services.report.load import Message
from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation


class RobotClock(msgspec.Struct, frozen=True):
    """Marks ``(t, robot)``: recorder time (s since the run start) and simulation time (s) of
    each ag_ex answer, in recorder order, robot time never going back (a mark that would is
    left out: a world restarted from its initial scene)."""

    marks: tuple[tuple[float, float], ...] = ()

    def at(self, t: float) -> float | None:
        """The robot time at recorder time ``t`` (s), interpolated between the marks around
        it; None before the first mark or after the last."""
        if not self.marks or t < self.marks[0][0] or t > self.marks[-1][0]:
            return None
        i = bisect.bisect_left(self.marks, (t, float("-inf")))
        if self.marks[i][0] == t or i == 0:
            return self.marks[i][1]
        (t0, r0), (t1, r1) = self.marks[i - 1], self.marks[i]
        return r0 + (r1 - r0) * (t - t0) / (t1 - t0) if t1 > t0 else r1

    def between(self, start: float | None, end: float | None) -> float | None:
        """Robot time from the first mark at or after ``start`` to the last at or before
        ``end`` (s of recorder time): the simulated time the robot spent in between, as far
        as its answers show; None when no mark lies between them."""
        if start is None or end is None:
            return None
        inside = [r for t, r in self.marks if start <= t <= end]
        return inside[-1] - inside[0] if inside else None


def robot_clock(messages: Sequence[Message]) -> RobotClock:
    """The clock's marks from ag_ex's ``inform``\\s on C5 among ``messages``."""
    marks: list[tuple[float, float]] = []
    for m in messages:
        if not m.is_("C5", "ag_ex", "inform"):
            continue
        content = m.content
        robot = (
            content.sim_time
            if isinstance(content, CommandResult)
            else content.stamp
            if isinstance(content, Observation)
            else None
        )
        if robot is not None and (not marks or (m.t >= marks[-1][0] and robot >= marks[-1][1])):
            marks.append((m.t, robot))
    return RobotClock(tuple(marks))
