"""ag_ex's watch: the head camera sees continuously while someone needs to know of changes
quickly (``ExecutorProcess.watch``, velma/executor/process.py).

A :class:`Watcher` is one thread on the communication side. It reads the latest whole
simulation state the loop copies into shared memory (``ExecutorProcess.world``: the simulation
time and ``qpos``, rewritten every ``WORLD_PERIOD`` cycles) every :data:`POLL_S` s of wall time
and, every ``period_s`` s of ROBOT time, makes it a watch frame (``WorldCapture`` with
``watch=True``: velma/executor/capture.py) that it hands to ``put`` — the executor's
``ResultDelivery`` (velma/executor/delivery.py), which observes it in the camera host's watch
mode (velma/executor/observer.py: one Kinect frame, the objects localised, no content count) in
order with the commands' results. Frames never queue up: at most one is in flight (put, not yet
delivered: :meth:`Watcher.delivered`); a frame that falls due while one is in flight is skipped
and counted (``skipped``), and the next is due ``period_s`` after the one skipped.

The loop never waits for a watch: it does not know of it, beyond its pace (``Pace``,
velma/executor/process.py): a camera frame costs wall time in simulation (0.1–0.6 s of software
GL, docs/bench/observe.md), so while a watch is on, a fleet that runs as fast as possible is
paced to at most ``watch_pace`` × wall time (ROCO_WATCH_PACE) so that the frames keep up.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from typing import Protocol

import numpy as np
import numpy.typing as npt

from velma.executor.capture import WorldCapture

log = logging.getLogger(__name__)

POLL_S = 0.01
"""Wall seconds between two reads of the latest simulation state (the loop rewrites it every
20 ms of robot time: velma/executor/loop_wire.py ``WORLD_PERIOD``)."""
PERIOD_RANGE_S = (0.05, 60.0)
"""Accepted ``period_s`` (robot s) of a watch."""


class State(Protocol):
    """What the watcher reads: ``sim_time`` (s) and MuJoCo's ``qpos`` (velma/executor/process.py
    ``WorldState``)."""

    @property
    def sim_time(self) -> float: ...

    @property
    def qpos(self) -> npt.NDArray[np.float64]: ...


def check_period(period_s: float) -> float:
    """``period_s`` when it is a watch period (:data:`PERIOD_RANGE_S`, robot s); raises
    ``ValueError`` with one line otherwise."""
    low, high = PERIOD_RANGE_S
    if not (isinstance(period_s, int | float) and math.isfinite(period_s) and low <= period_s <= high):
        raise ValueError(f"a watch period is {low}..{high} s of robot time, not {period_s}")
    return float(period_s)


class Watcher:
    """The watch's thread (module docstring): frames of ``objects`` (empty: every object the
    camera knows) every ``period_s`` s of robot time from the states ``world()`` gives (None:
    none yet), each handed to ``put``. Raises ``ValueError`` for a period out of
    :data:`PERIOD_RANGE_S`. Call :meth:`delivered` when a frame was delivered, :meth:`stop`
    to end it."""

    def __init__(
        self,
        world: Callable[[], State | None],
        put: Callable[[WorldCapture], None],
        objects: tuple[str, ...],
        period_s: float,
        *,
        poll_s: float = POLL_S,
    ) -> None:
        self.objects = objects
        self.period_s = check_period(period_s)
        self._world = world
        self._put = put
        self._poll_s = poll_s
        self._lock = threading.Lock()
        self._in_flight = False
        self._next: float | None = None  # robot time (s) the next frame is due at
        self.frames = 0
        """Frames put so far."""
        self.skipped = 0
        """Frames that fell due while one was in flight (not made)."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="velma-watch", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._poll_s):
            try:
                self.step()
            except Exception:  # a state that cannot be read must not end the watch
                log.exception("the watch could not make a frame")

    def step(self) -> bool:
        """Read the latest state once; put a frame when one is due and none is in flight.
        Returns True when it put one (the thread calls it every ``poll_s`` s)."""
        state = self._world()
        if state is None:
            return False
        with self._lock:
            if self._next is not None and state.sim_time < self._next:
                return False
            if self._in_flight:
                assert self._next is not None
                self.skipped += 1
                self._next += self.period_s
                return False
            self._in_flight = True
            self._next = state.sim_time + self.period_s
            self.frames += 1
        self._put(WorldCapture.of(self.objects, state.sim_time, state.qpos, watch=True))
        return True

    def delivered(self) -> None:
        """The frame in flight was delivered (observed or failed): the next may be put."""
        with self._lock:
            self._in_flight = False

    def stop(self, timeout: float = 5.0) -> None:
        """End the thread (waits up to ``timeout`` s); a frame in flight is still delivered."""
        self._stop.set()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)
