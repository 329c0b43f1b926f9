"""The fleet's clock: the time an agent's periodic behaviours run on.

When the fleet runs as fast as possible (``ROCO_REALTIME=0``, ``roco run`` without
``--realtime``) the simulation runs several times faster than the wall clock, so a behaviour
that acts every 2 s of wall time acts once per several seconds of the robot's world. ag_ex
publishes the simulation's time (s) on ``roco/sim/clock`` (:data:`services.runtime.keys.SIM_CLOCK`,
:func:`encode_sim_time`) at its state rate (20 Hz, wall); every agent hears it
(services/runtime/engine.py ``Engine.bind``) and marks its :class:`FleetClock`, which then runs
at the simulation's pace. In real time (``ROCO_REALTIME=1``) the agents do not listen and the
clock is the wall clock.

The clock's readings are seconds from an arbitrary origin (its wall clock's until the first
mark), never going back; between marks it runs on at the pace the last two marks gave; after
:data:`STALE_S` without a mark (ag_ex gone, no simulation) at the wall clock's pace again.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable

STALE_S = 1.0
"""Wall seconds after the last mark beyond which the clock runs at the wall clock's pace (the
marks come every 0.05 s while ag_ex runs)."""
MIN_PACE = 0.01
"""The slowest pace (clock s per wall s) :meth:`FleetClock.wall_seconds` assumes: a paused
simulation does not make a waiting agent wait without end."""

_SIM_TIME = struct.Struct("<d")


def encode_sim_time(sim_s: float) -> bytes:
    """The payload of ``roco/sim/clock``: the simulation's time ``sim_s`` (s), an IEEE 754
    double, little-endian (8 bytes)."""
    return _SIM_TIME.pack(sim_s)


def decode_sim_time(payload: bytes) -> float:
    """The simulation's time (s) in a ``roco/sim/clock`` payload; raises ValueError for a
    payload that is not 8 bytes or not a finite number."""
    if len(payload) != _SIM_TIME.size:
        raise ValueError(f"a simulation time is {_SIM_TIME.size} bytes, not {len(payload)}")
    (sim_s,) = _SIM_TIME.unpack(payload)
    if sim_s != sim_s or sim_s in (float("inf"), float("-inf")):
        raise ValueError(f"a simulation time is a finite number, not {sim_s}")
    return float(sim_s)


class FleetClock:
    """The fleet's clock (module docstring): call it for the time (s); :meth:`mark` it with the
    simulation's time as it is heard; :meth:`wall_seconds` converts a duration on it to wall
    seconds (how long an agent blocks until a period is due). ``wall`` is the wall clock it
    runs on between marks (s, monotonic; an agent's ``sources.monotonic``). Thread-safe: marks
    come on the transport's thread, readings on the agent's."""

    def __init__(self, wall: Callable[[], float] = time.monotonic) -> None:
        self.wall = wall
        self.pace = 1.0
        """Clock seconds per wall second, from the last two marks (1 before two marks)."""
        self._lock = threading.Lock()
        self._offset = 0.0  # clock time minus simulation time
        self._mark: tuple[float, float] | None = None  # (simulation s, wall s) of the last mark
        self._last = float("-inf")  # the latest reading: the clock never goes back

    def __call__(self) -> float:
        with self._lock:
            return self._read(self.wall())

    def _read(self, w: float) -> float:
        if self._mark is None:
            t = w
        else:
            sim, at = self._mark
            dt = w - at
            t = sim + self._offset + self.pace * min(dt, STALE_S) + max(0.0, dt - STALE_S)
        self._last = max(self._last, t)
        return self._last

    def mark(self, sim_s: float) -> None:
        """The simulation's time is ``sim_s`` (s) now. The first mark, one that goes back (a
        world started again) and one after :data:`STALE_S` without a mark keep the clock where
        it is and run it from there."""
        with self._lock:
            w = self.wall()
            now = self._read(w)
            previous = self._mark
            if previous is None or sim_s < previous[0] or w - previous[1] > STALE_S:
                self._offset = now - sim_s
                self.pace = 1.0
            elif w > previous[1]:
                self.pace = (sim_s - previous[0]) / (w - previous[1])
            self._mark = (sim_s, w)

    def fresh(self) -> bool:
        """Whether a mark came within the last :data:`STALE_S` wall seconds."""
        mark = self._mark
        return mark is not None and self.wall() - mark[1] <= STALE_S

    def wall_seconds(self, seconds: float) -> float:
        """The wall seconds ``seconds`` of this clock take at its current pace (never slower
        than :data:`MIN_PACE`; the wall clock's pace once stale)."""
        pace = max(self.pace, MIN_PACE) if self.fresh() else 1.0
        return seconds / pace
