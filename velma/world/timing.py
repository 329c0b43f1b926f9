"""The world process's own timing (velma/world/serve.py): what its cycle counts, how, and the
figures read from the counts (``WorldTiming``).

Per run (since the world process started), with ``DT`` = 1 ms the world's period:

- *cycles*: physics steps;
- *paced cycles*: cycles due at a wall-clock time (real-time pacing, or while the safety
  layer holds the robot in lockstep); only these can be late or reset the schedule;
- *late*: a paced cycle that started more than ``LATE_AFTER_S`` (one period) after it was due
  (the sleep woke late, or the step before took longer than a period); ``late_max_us`` is the
  worst such delay;
- *schedule resets*: a paced cycle more than ``MAX_BEHIND_S`` late; the world goes on from
  now instead of stepping the missed cycles in a burst (the simulation falls behind the
  wall clock by the gap);
- *stalls*: a gap of more than ``STALL_PERIODS`` periods between the starts of two
  consecutive cycles, less the time the world waited for the controller's command in between:
  the world itself was held up (descheduled, a long step), in either pacing;
  ``gap_max_us`` is the longest such gap;
- *stale commands* (real-time pacing): a step applied with a command that answers an older
  state than the newest it could answer (cycle k applies the command for state k − 1 at best);
  its *age* is how many cycles older (1 … ``HOLD_CYCLES`` − 1: older than that, the robot is
  held instead), counted per age, with the worst age;
- *held*: steps with no command applied (the safety layer held the robot: before a controller
  attached, after one ended, or when its command came too late); *held while attached*: those
  between two applied commands (a controller there on both sides: its command came too late);
- *waits* (lockstep, as fast as possible): cycles whose command was not yet there when the
  world had stepped and published, so that the world waited for the controller
  (``wait_max_us`` the longest wait). In lockstep no cycle is due at a wall-clock time and
  every applied command is the newest (the world waits for it), so only waits and holds say
  how the pair kept pace.

The counts are Python integers in the world's loop (a few comparisons a cycle, nothing
allocated, nothing logged) and are copied every ``PUBLISH_CYCLES`` cycles, and when the world
stops, into int64 slots of the robot link's block (velma/world/link.py ``counters``), where any
process attached to the link reads them (``WorldTiming.read``). Each slot is one aligned
8-byte store: a reader may see two slots from different copies, never a torn number.
"""

from __future__ import annotations

import msgspec
import numpy as np
import numpy.typing as npt

DT = 0.001
"""The world's period (s): velma/world/hardware.py ``DT``, repeated so that this module (read
by the report) imports no MuJoCo."""
HOLD_CYCLES = 5
"""States a controller may leave unanswered before the safety layer holds the robot (real
time): a command answering state k − ``HOLD_CYCLES`` or later still applies at cycle k."""
MAX_BEHIND_S = 0.1
"""How far (s) a paced world may fall behind the wall clock before it stops catching up."""
LATE_AFTER_S = DT
"""Lateness (s) past which a paced cycle counts as late: one period."""
STALL_PERIODS = 10
"""Periods between two cycle starts (less the waits for the controller) that make a stall."""
PUBLISH_CYCLES = 100
"""Cycles between two copies of the counts into the link."""

N_AGES = HOLD_CYCLES - 1
"""Ages (1 … ``N_AGES`` cycles) a stale command that still applies can have."""
FIELDS = (
    "realtime",
    "cycles",
    "paced",
    "late",
    "late_max_ns",
    "resets",
    "stalls",
    "gap_max_ns",
    "held",
    "waits",
    "wait_max_ns",
    "stale",
    "stale_worst_age",
    "held_attached",
)
"""The slots of the counts, in order; the per-age stale counts follow (``N_AGES`` slots)."""
N_SLOTS = len(FIELDS) + N_AGES
_AT = {name: i for i, name in enumerate(FIELDS)}


class WorldTiming(msgspec.Struct, frozen=True, kw_only=True):
    """The world process's timing over its run so far (module docstring); times in µs.

    ``pacing`` is ``realtime`` or ``fast``; ``stale_by_age[i]`` counts the stale commands of
    age i + 1 cycles."""

    pacing: str
    cycles: int
    paced: int
    late: int
    late_max_us: float
    resets: int
    stalls: int
    gap_max_us: float
    held: int
    held_attached: int = 0
    waits: int
    wait_max_us: float
    stale: int
    stale_worst_age: int
    stale_by_age: tuple[int, ...]

    @classmethod
    def read(cls, slots: npt.NDArray[np.int64]) -> WorldTiming:
        """The figures of ``slots`` (at least ``N_SLOTS`` int64, as ``WorldClock`` writes
        them). Raises ValueError when there are fewer."""
        if slots.shape[0] < N_SLOTS:
            raise ValueError(f"{slots.shape[0]} slots, the world's timing needs {N_SLOTS}")
        v = [int(x) for x in slots[:N_SLOTS]]
        at = _AT
        return cls(
            pacing="realtime" if v[at["realtime"]] else "fast",
            cycles=v[at["cycles"]],
            paced=v[at["paced"]],
            late=v[at["late"]],
            late_max_us=v[at["late_max_ns"]] / 1e3,
            resets=v[at["resets"]],
            stalls=v[at["stalls"]],
            gap_max_us=v[at["gap_max_ns"]] / 1e3,
            held=v[at["held"]],
            held_attached=v[at["held_attached"]],
            waits=v[at["waits"]],
            wait_max_us=v[at["wait_max_ns"]] / 1e3,
            stale=v[at["stale"]],
            stale_worst_age=v[at["stale_worst_age"]],
            stale_by_age=tuple(v[len(FIELDS) :]),
        )


class WorldClock:
    """The counts of one world run (module docstring), kept by the world's loop.

    Times are seconds of one monotonic clock (``time.perf_counter`` in the world). The loop
    calls ``started`` at the start of every cycle, ``waited`` after a wait for the
    controller's command, ``applied`` for each step's command and ``publish`` to copy the
    counts into ``slots`` (an int64 array of ``N_SLOTS``, e.g. the link's ``counters``)."""

    def __init__(self, slots: npt.NDArray[np.int64] | None = None, *, realtime: bool) -> None:
        if slots is not None and slots.shape[0] < N_SLOTS:
            raise ValueError(f"{slots.shape[0]} slots, the world's timing needs {N_SLOTS}")
        self.slots = slots
        self.realtime = realtime
        self.cycles = self.paced = self.late = self.resets = self.stalls = 0
        self.late_max = self.gap_max = self.wait_max = 0.0
        self.held = self.waits = self.stale = self.stale_worst_age = 0
        self.held_attached = 0
        self._attached = False  # a command was applied before
        self._holding = 0  # steps held since the last applied command
        self.by_age = [0] * N_AGES
        self._last_start: float | None = None
        self._waited = 0.0  # s waited for the controller since the last cycle start

    def started(self, start: float, due: float | None) -> bool:
        """Count a cycle that starts at ``start``; ``due``: when it was due (paced), None in
        lockstep. Returns True when it is more than ``MAX_BEHIND_S`` late: the caller then
        resets its schedule to ``start`` (counted here)."""
        self.cycles += 1
        last, self._last_start = self._last_start, start
        if last is not None:
            gap = start - last - self._waited
            if gap > self.gap_max:
                self.gap_max = gap
            if gap > STALL_PERIODS * DT:
                self.stalls += 1
        self._waited = 0.0
        if due is None:
            return False
        self.paced += 1
        lateness = start - due
        if lateness <= LATE_AFTER_S:
            return False
        self.late += 1
        if lateness > self.late_max:
            self.late_max = lateness
        if lateness > MAX_BEHIND_S:
            self.resets += 1
            return True
        return False

    def waited(self, seconds: float) -> None:
        """Count a wait of ``seconds`` for the controller's command (lockstep)."""
        self.waits += 1
        self._waited += seconds
        if seconds > self.wait_max:
            self.wait_max = seconds

    def applied(self, cycle: int, answered: int | None) -> None:
        """Count the command step ``cycle`` applies: the one answering state ``answered``,
        or None when the robot is held. The newest it could answer is ``cycle`` − 1."""
        if answered is None:
            self.held += 1
            self._holding += 1
            return
        if self._attached:
            self.held_attached += self._holding
        self._attached, self._holding = True, 0
        age = cycle - 1 - answered
        if age > 0:
            self.stale += 1
            self.by_age[min(age, N_AGES) - 1] += 1
            if age > self.stale_worst_age:
                self.stale_worst_age = age

    def publish(self) -> None:
        """Copy the counts into ``slots`` (nothing without them)."""
        slots = self.slots
        if slots is None:
            return
        values = (
            int(self.realtime),
            self.cycles,
            self.paced,
            self.late,
            round(self.late_max * 1e9),
            self.resets,
            self.stalls,
            round(self.gap_max * 1e9),
            self.held,
            self.waits,
            round(self.wait_max * 1e9),
            self.stale,
            self.stale_worst_age,
            self.held_attached,
            *self.by_age,
        )
        slots[:N_SLOTS] = values

    def figures(self) -> WorldTiming:
        """The counts as figures (the same as ``WorldTiming.read`` of the slots after
        ``publish``)."""
        out = np.zeros(N_SLOTS, dtype=np.int64)
        slots, self.slots = self.slots, out
        try:
            self.publish()
        finally:
            self.slots = slots
        return WorldTiming.read(out)
