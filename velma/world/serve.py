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
"""

from __future__ import annotations

import time
from collections.abc import Callable
from multiprocessing.connection import Connection

import numpy as np

from velma.world.hardware import DT, SimulatedVelma
from velma.world.layout import COMMAND, MEASURED
from velma.world.link import RobotLink

HOLD_CYCLES = 5
"""States a controller may leave unanswered before the safety layer holds the robot."""
LOCKSTEP_WAIT_S = 0.5
"""How long (wall s) the world waits for a command in lockstep before it holds: far above a
cycle's work (≈ 0.3 ms), so that only a controller that is gone or stuck causes a hold."""
MAX_BEHIND_S = 0.1
"""How far (s) a paced world may fall behind the wall clock before it stops catching up."""
STOP_CHECK_CYCLES = 100
"""Cycles between two calls of ``should_stop``."""


def serve(
    sim: SimulatedVelma,
    link: RobotLink,
    *,
    realtime: bool,
    should_stop: Callable[[], bool],
    max_cycles: int | None = None,
) -> int:
    """Step ``sim`` and serve it on ``link`` (module docstring) until ``should_stop()`` says so
    (asked every ``STOP_CHECK_CYCLES`` cycles) or ``max_cycles`` cycles ran; returns the
    number of cycles. The scene goes with every measured state when the link has room for
    it (``sim.scene_size`` values). Raises what the physics raises."""
    measured, command = np.zeros(MEASURED.size), np.zeros(COMMAND.size)
    scene = np.zeros(link.n_scene) if link.n_scene == sim.scene_size else None
    k = 0
    due = time.perf_counter()  # wall time the next cycle is due, while paced
    while max_cycles is None or k < max_cycles:
        if k % STOP_CHECK_CYCLES == 0 and should_stop():
            break
        sim.measure(measured)
        if scene is not None:
            sim.scene(scene)
            link.publish_scene(k, scene)
        link.publish(k, measured)
        fresh = False
        if k > 0:
            if not (realtime or sim.holding):
                link.wait_command(k - 1, LOCKSTEP_WAIT_S, spin_s=0.0)
            answered = link.read_command(command)
            # in lockstep every cycle has its command (also to leave a hold), or the
            # controller is gone
            fresh = answered is not None and answered >= (k - HOLD_CYCLES if realtime else k - 1)
        sim.apply(command if fresh else None)
        sim.step()
        k += 1
        if realtime or sim.holding:
            due += DT
            left = due - time.perf_counter()
            if left > 0:
                time.sleep(left)
            elif left < -MAX_BEHIND_S:  # far behind (a stall): go on from now, no burst
                due = time.perf_counter()
        else:
            due = time.perf_counter()
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
