"""The world's cycle: Velma's hardware side (velma/world/hardware.py) stepped at 1 kHz and
served on the robot link (velma/world/link.py) to whichever controller attaches.

Per cycle k the world publishes the measured state k, takes the controller's command for the
state before (k − 1: the controller computes while the physics steps, as under FRI, where a
command applies in the cycle after the state it answers) and steps.

- **Lockstep** (``realtime=False``, the fast mode of ``roco run``): the world waits for that
  command up to ``LOCKSTEP_WAIT_S``, so the simulation runs as fast as the two can go and
  every cycle gets its command.
- **Real time** (``realtime=True``): cycle k starts at wall time t₀ + k·``DT``; the world applies
  the latest command it has, as a robot applies the last FRI command.

When no command answers one of the last ``HOLD_CYCLES`` states in real time, or the state
before in lockstep (the controller ended, hangs or has not attached yet), the safety layer
holds the robot and the world steps on the wall clock until a controller commands again: the
kitchen goes on, and a controller that attaches finds it as it is now.

A paced world more than ``MAX_BEHIND_S`` behind the wall clock goes on from now instead of
catching up in a burst. Late and stalled cycles, those resets, stale commands, holds and the
waits for the controller are counted into the link (velma/world/timing.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from multiprocessing.connection import Connection

import numpy as np

from velma.world.hardware import DT, SimulatedVelma
from velma.world.layout import COMMAND, MEASURED
from velma.world.link import RobotLink
from velma.world.timing import HOLD_CYCLES, MAX_BEHIND_S, PUBLISH_CYCLES, WorldClock

__all__ = ["HOLD_CYCLES", "LOCKSTEP_WAIT_S", "MAX_BEHIND_S", "serve", "world_process"]

LOCKSTEP_WAIT_S = 0.5
"""How long (wall s) the world waits for a command in lockstep before it holds: far above a
cycle's work (≈ 0.3 ms), so that only a controller that is gone or stuck causes a hold."""
STOP_CHECK_CYCLES = PUBLISH_CYCLES
"""Cycles between two calls of ``should_stop`` (and two copies of the timing counts)."""


def serve(
    sim: SimulatedVelma,
    link: RobotLink,
    *,
    realtime: bool,
    should_stop: Callable[[], bool],
    max_cycles: int | None = None,
    clock: Callable[[], float] = time.perf_counter,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Step ``sim`` and serve it on ``link`` (module docstring) until ``should_stop()`` says so
    (asked every ``STOP_CHECK_CYCLES`` cycles) or ``max_cycles`` cycles ran; returns the
    number of cycles. The scene goes with every measured state when the link has room for
    it (``sim.scene_size`` values). The world's timing is counted (velma/world/timing.py
    ``WorldClock``) into ``link.counters``, copied every ``STOP_CHECK_CYCLES`` cycles and at
    the end. ``clock`` (s, monotonic) and ``sleep`` pace the cycle (a test's own clock may
    stand in). Raises what the physics raises."""
    measured, command = np.zeros(MEASURED.size), np.zeros(COMMAND.size)
    scene = np.zeros(link.n_scene) if link.n_scene == sim.scene_size else None
    counts = WorldClock(link.counters, realtime=realtime)
    k = 0
    due: float | None = None  # wall time the cycle is due, while paced (None: in lockstep)
    if realtime or sim.holding:
        due = clock()
    try:
        while max_cycles is None or k < max_cycles:
            if k % STOP_CHECK_CYCLES == 0:
                counts.publish()
                if should_stop():
                    break
            start = clock()
            if counts.started(start, due):  # far behind (a stall): go on from now, no burst
                due = start
            sim.measure(measured)
            if scene is not None:
                sim.scene(scene)
                link.publish_scene(k, scene)
            link.publish(k, measured)
            answered: int | None = None
            if k > 0:
                if not (realtime or sim.holding):
                    latest = link.command_cycle()
                    if latest is None or latest < k - 1:  # not there yet: the world waits
                        t = clock()
                        link.wait_command(k - 1, LOCKSTEP_WAIT_S, spin_s=0.0)
                        counts.waited(clock() - t)
                answered = link.read_command(command)
                # in lockstep every cycle has its command (also to leave a hold), or the
                # controller is gone
                if answered is not None and answered < (k - HOLD_CYCLES if realtime else k - 1):
                    answered = None
            counts.applied(k, answered)
            sim.apply(command if answered is not None else None)
            sim.step()
            k += 1
            if realtime or sim.holding:
                due = (clock() if due is None else due) + DT
                left = due - clock()
                if left > 0:
                    sleep(left)
            else:
                due = None
    finally:
        counts.publish()
    return k


def world_process(conn: Connection, *, realtime: bool, seed: int = 0) -> None:
    """Body of a world process (spawned): make the kitchen and its link, say the link's name
    on ``conn``, serve until ``conn`` says ``"stop"`` (or closes), remove the link."""
    sim = SimulatedVelma(seed=seed)
    link = RobotLink.create(MEASURED.size, COMMAND.size, sim.scene_size)
    try:
        conn.send(link.name)

        def should_stop() -> bool:
            try:
                return conn.poll() and conn.recv() == "stop"
            except (EOFError, OSError):
                return True

        serve(sim, link, realtime=realtime, should_stop=should_stop)
    finally:
        link.close()
