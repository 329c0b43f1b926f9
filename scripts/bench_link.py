"""What the world/controller split costs a lockstep cycle (velma/world/link.py).

Two processes (spawn) in lockstep as the world and ag_ex's controller would run in the fast
mode: per cycle the world works ``--world-us`` (the physics step), publishes its measured
state and waits for the command; the controller waits for the state, works
``--controller-us`` (the impedance law) and writes the command. Work is a busy loop on the
clock (CPU time, as the physics' and the law's). The baseline does the same work in one
process, one part after the other. For each waiting policy (spin ``S`` µs, then sleep on the
futex doorbell) it prints the wall time per cycle (p50, p99, mean, µs), the overhead on the
mean against the baseline, and the CPU time the two processes used per cycle (spinning burns
it; the fleet's agents and the camera need it). ``--load`` adds a process that keeps one CPU
busy, as a fleet at work does on a 2-core machine.

    python scripts/bench_link.py [--cycles 20000] [--world-us 260] [--controller-us 70] [--load]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from velma.world.link import RobotLink

N_MEASURED, N_COMMAND = 120, 40
"""Numbers per cycle each way (of the order of Velma's: joints, velocities, F/T, hands)."""
TIMEOUT_S = 5.0


def busy(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def controller(name: str, cycles: int, work_s: float, spin_s: float, conn: Connection) -> None:
    link = RobotLink.attach(name)
    measured, command = np.zeros(N_MEASURED), np.zeros(N_COMMAND)
    conn.send("ready")
    cpu0 = time.process_time()
    for k in range(cycles):
        if not link.wait_measured(k, TIMEOUT_S, spin_s):
            raise SystemExit(f"controller: no state for cycle {k}")
        link.read_measured(measured)
        busy(work_s)
        command[0] = measured[0]
        link.command(k, command)
    conn.send(time.process_time() - cpu0)
    link.close()


def hog(conn: Connection) -> None:
    conn.send("ready")
    while not conn.poll():
        busy(0.01)


def lockstep(
    cycles: int, world_s: float, controller_s: float, spin_s: float, lag: bool
) -> tuple[np.ndarray, float]:
    """Wall time of each cycle (s) and the CPU time per cycle of both processes (s). ``lag``:
    the world steps with the command computed from the state one cycle before (the
    controller's work runs beside the step), else with the command of the state it just
    published (the two work one after the other)."""
    ctx = multiprocessing.get_context("spawn")
    link = RobotLink.create(N_MEASURED, N_COMMAND)
    here, there = ctx.Pipe()
    proc = ctx.Process(target=controller, args=(link.name, cycles, controller_s, spin_s, there))
    proc.start()
    try:
        assert here.recv() == "ready"
        measured, command = np.zeros(N_MEASURED), np.zeros(N_COMMAND)
        walls = np.empty(cycles)
        cpu0 = time.process_time()
        t = time.perf_counter()
        for k in range(cycles):
            measured[0] = k
            link.publish(k, measured)
            # lag: the step uses the command of the state before (the law runs beside it)
            answered = k - 1 if lag else k
            if answered >= 0 and not link.wait_command(answered, TIMEOUT_S, spin_s):
                raise SystemExit(f"world: no command for cycle {answered}")
            link.read_command(command)
            busy(world_s)
            now = time.perf_counter()
            walls[k], t = now - t, now
        cpu = time.process_time() - cpu0 + float(here.recv())
    finally:
        proc.join(10)
        link.close()
    return walls, cpu / cycles


def serial(cycles: int, world_s: float, controller_s: float) -> np.ndarray:
    walls = np.empty(cycles)
    t = time.perf_counter()
    for k in range(cycles):
        busy(world_s)
        busy(controller_s)
        now = time.perf_counter()
        walls[k], t = now - t, now
    return walls


def row(label: str, walls: np.ndarray, base: float, cpu: float | None) -> str:
    us = walls * 1e6
    mean = float(us.mean())
    cpu_text = f"{cpu * 1e6:.0f}" if cpu is not None else "—"
    over = f"{(mean / base - 1) * 100:+.1f} %" if base else "—"
    p50, p99 = np.percentile(us, 50), np.percentile(us, 99)
    return f"| {label} | {p50:.0f} | {p99:.0f} | {mean:.0f} | {over} | {cpu_text} |"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=20000)
    ap.add_argument("--world-us", type=float, default=260.0)
    ap.add_argument("--controller-us", type=float, default=70.0)
    ap.add_argument(
        "--spins-us", default="0,20,100,100000", help="waiting policies: spin µs before the futex"
    )
    ap.add_argument("--load", action="store_true", help="one more process keeps a CPU busy")
    ap.add_argument("--lag", action="store_true", help="the command applies one cycle later (overlapped)")
    a = ap.parse_args()
    world_s, controller_s = a.world_us * 1e-6, a.controller_us * 1e-6
    hogger = None
    if a.load:
        ctx = multiprocessing.get_context("spawn")
        stop, there = ctx.Pipe()
        hogger = ctx.Process(target=hog, args=(there,))
        hogger.start()
        assert stop.recv() == "ready"
    try:
        print(
            f"{a.cycles} cycles; work per cycle: world {a.world_us:.0f} µs, controller "
            f"{a.controller_us:.0f} µs; {os.cpu_count()} CPUs; "
            f"load: {'one busy process' if a.load else 'none'}; "
            f"command applied {'one cycle later' if a.lag else 'in the cycle of its state'}"
        )
        print("\n| waiting | wall p50 µs | p99 µs | mean µs | vs one process | CPU µs per cycle |")
        print("|---|---|---|---|---|---|")
        base_walls = serial(a.cycles, world_s, controller_s)
        base = float(base_walls.mean() * 1e6)
        print(row("one process (baseline)", base_walls, 0.0, None))
        for spin_us in (float(x) for x in a.spins_us.split(",")):
            walls, cpu = lockstep(a.cycles, world_s, controller_s, spin_us * 1e-6, a.lag)
            label = (
                "spin only"
                if spin_us >= 1e4
                else ("futex only" if spin_us == 0 else f"spin {spin_us:.0f} µs, then futex")
            )
            print(row(label, walls, base, cpu), flush=True)
    finally:
        if hogger is not None:
            stop.send("stop")
            hogger.join(5)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
