"""What running the world in a process of its own costs the fast mode, on the real work: the
kitchen's physics with Velma's servos (velma/world/hardware.py) and the two-arm impedance law
(velma/control/compiled.py) holding the arms while the torso turns 0.3 rad.

- ``one process``: per cycle measure, law, apply, step, one after the other;
- ``two processes``: the world (velma/world/serve.py, lockstep) in one, the law in the other,
  across the robot link (velma/world/link.py), the command applied in the cycle after its
  state (the law computes while the physics steps).

Prints the wall time per cycle (mean, p50, p99, µs) and the ratio of the means.

    python scripts/bench_world.py [--cycles 5000]
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from velma.control.compiled import make_controller
from velma.control.joints import HEAD_JOINTS, SIDES
from velma.control.robot_model import RobotModel
from velma.world.hardware import DT, SimulatedVelma
from velma.world.layout import COMMAND, MEASURED
from velma.world.link import RobotLink
from velma.world.serve import world_process

TURN = 0.3
Q, V, TAU, HAND, HEAD = (
    MEASURED.slice("q"),
    MEASURED.slice("v"),
    COMMAND.slice("tau"),
    COMMAND.slice("hand"),
    COMMAND.slice("head"),
)


class Law:
    """The impedance law at the first measured pose, the torso turned by ``TURN``."""

    def __init__(self, measured: np.ndarray) -> None:
        robot = RobotModel()
        self.ctrl = make_controller(robot, DT)
        self.head = [robot.v_index(j) for j in HEAD_JOINTS]
        q, v = measured[Q].copy(), measured[V].copy()
        for s in SIDES:
            self.ctrl.arm[s].q = q[self.ctrl.arm_slice[s]].copy()
        self.ctrl.torso_q = float(q[self.ctrl.torso_idx]) + TURN
        self.ctrl.kinematics(q, v)
        self.command = np.zeros(COMMAND.size)
        self.command[HAND] = 0.0  # hand sequence 0: no hand command
        self.command[HEAD] = q[self.head]

    def __call__(self, measured: np.ndarray) -> np.ndarray:
        taus, tau_torso = self.ctrl.update(measured[Q].copy(), measured[V].copy())
        self.command[TAU] = np.concatenate([taus["right"], taus["left"], [tau_torso]])
        return self.command


def one_process(cycles: int) -> np.ndarray:
    sim = SimulatedVelma()
    measured = np.zeros(MEASURED.size)
    sim.measure(measured)
    law = Law(measured)
    walls = np.empty(cycles)
    t = time.perf_counter()
    for k in range(cycles):
        sim.measure(measured)
        sim.apply(law(measured))
        sim.step()
        now = time.perf_counter()
        walls[k], t = now - t, now
    return walls


def two_processes(cycles: int) -> np.ndarray:
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe()
    proc = ctx.Process(target=world_process, args=(there,), kwargs={"realtime": False})
    proc.start()
    try:
        link = RobotLink.attach(here.recv())
        measured = np.zeros(MEASURED.size)
        assert link.wait_measured(0, 60.0, spin_s=0.0)
        k = link.read_measured(measured)
        assert k is not None
        law = Law(measured)
        walls = np.empty(cycles)
        for _ in range(50):  # leave the hold the world starts in
            link.command(k, law(measured))
            link.wait_measured(k + 1, 10.0, spin_s=0.0)
            k = link.read_measured(measured)
            assert k is not None
        t = time.perf_counter()
        for i in range(cycles):
            link.command(k, law(measured))
            link.wait_measured(k + 1, 10.0, spin_s=0.0)
            k = link.read_measured(measured)
            assert k is not None
            now = time.perf_counter()
            walls[i], t = now - t, now
        link.close()
    finally:
        here.send("stop")
        proc.join(30)
    return walls


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=5000)
    a = ap.parse_args()
    print(f"{a.cycles} cycles of the kitchen, the law holding the arms and turning the torso\n")
    print("| setup | mean µs | p50 µs | p99 µs |")
    print("|---|---|---|---|")
    means = []
    for label, run in (("one process", one_process), ("two processes (world, law)", two_processes)):
        us = run(a.cycles) * 1e6
        means.append(float(us.mean()))
        print(f"| {label} | {us.mean():.0f} | {np.percentile(us, 50):.0f} | {np.percentile(us, 99):.0f} |")
    print(f"\ntwo processes / one process (means): {means[1] / means[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
