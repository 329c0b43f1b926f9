"""Benchmark of Velma's two-arm controller (velma/control/impedance.py) in the kitchen scene.

Each law is measured in turn (``--law``): the compiled one (velma/control/compiled.py) and
its Python reference (``VelmaController``).

Builds ``Runtime(seed=0)`` (the kitchen with its spheres), puts both arms in Cartesian
impedance at their current grip pose (null-space posture: the current configuration), and
times, with ``time.perf_counter`` over ``--cycles`` cycles after ``--warmup`` cycles:

- ``controller``: the law's ``update(q, v)`` (both arms Cartesian, plus the torso),
  as called by ``Runtime.cycle``;
- ``mj_step``: ``mujoco.mj_step`` as called by ``Runtime.cycle``;
- ``controller + mj_step``: the sum of both in the same cycle;
- ``Runtime.cycle``: the whole cycle (state read, controller, hands, head, mj_step, the
  contact scan every 10 cycles);
- ``controller, safety active``: ``update`` of a second controller on the same states with
  every safety term forced on (bands 1.5 rad wide, velocity limit 0): the worst path.

Prints one table per repeat (p50 / p99 / max in µs) and what it ran on. The timing target
(the controller alone at p99, services/bench/targets.py ``CONTROLLER_P99``) is checked and
reported, not asserted: run it on a quiet machine and repeat, the figures on a shared 2-core
machine are noisy.

Usage: ``python scripts/bench_controller.py [--cycles 5000] [--warmup 500] [--repeats 3]
[--law compiled|python|both]``
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time
from collections.abc import Callable
from typing import Any

import benchlib  # scripts/benchlib.py, beside this file
import mujoco
import numpy as np
import pinocchio as pin

from services.bench import targets
from velma.control.compiled import ENV_LAW, compiled_available
from velma.control.joints import SIDES
from velma.control.robot_model import RobotModel
from velma.executor.runtime import Runtime

TARGET_P99_US = targets.CONTROLLER_P99.limit  # the controller alone, µs


def cpu_model() -> str:
    """The CPU model name (scripts/benchlib.py)."""
    return benchlib.cpu_model()


def describe() -> str:
    """The machine and the versions the figures were measured with."""
    cores = os.cpu_count()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cores
    return (
        f"CPU: {cpu_model()}, {cores} cores ({usable} usable)\n"
        f"Python {platform.python_version()}, pinocchio {pin.__version__}, mujoco {mujoco.__version__}, "
        f"numpy {np.__version__}, {platform.system()} {platform.release()}"
    )


def load() -> str:
    """The 1-minute load average (other processes compete for the 2 cores)."""
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except OSError:
        return "?"


def timed(fn: Callable[..., Any], sink: list[float]) -> Callable[..., Any]:
    """``fn`` wrapped to append its duration (s) to ``sink``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        sink.append(time.perf_counter() - t0)
        return out

    return wrapper


def stats(seconds: list[float]) -> tuple[float, float, float]:
    """p50, p99, max in µs."""
    us = np.asarray(seconds) * 1e6
    return float(np.percentile(us, 50)), float(np.percentile(us, 99)), float(us.max())


def run(cycles: int, warmup: int, law: str) -> dict[str, list[float]]:
    """One measurement (a fresh Runtime with the control law ``law``: ``compiled`` or
    ``python``); durations in s per row."""
    os.environ[ENV_LAW] = law
    rt = Runtime(seed=0)
    for side in SIDES:
        cmd = rt.ctrl.arm[side]
        cmd.mode = "cart"
        cmd.pose = rt.grip(side).copy()
        cmd.posture = rt.arm_q(side)
        cmd.twist = np.zeros(6)
    worst = type(rt.ctrl)(RobotModel(), rt.ctrl.dt)
    worst.limits = dataclasses.replace(
        worst.limits, limit_band=1.5, singularity_band=1.5, arm_velocity=0.0, torso_velocity=0.0
    )
    for side in SIDES:
        worst.arm[side] = rt.ctrl.arm[side]
    ctrl_t: list[float] = []
    step_t: list[float] = []
    original_update = rt.ctrl.update
    original_step = mujoco.mj_step
    rt.ctrl.update = timed(original_update, ctrl_t)  # type: ignore[method-assign]
    mujoco.mj_step = timed(original_step, step_t)
    try:
        for _ in range(warmup):
            rt.cycle()
        ctrl_t.clear()
        step_t.clear()
        cycle_t: list[float] = []
        worst_t: list[float] = []
        for _ in range(cycles):
            t0 = time.perf_counter()
            rt.cycle()
            t1 = time.perf_counter()
            cycle_t.append(t1 - t0)
            q, v = rt.q(), rt.v()
            t2 = time.perf_counter()
            worst.update(q, v)
            worst_t.append(time.perf_counter() - t2)
    finally:
        mujoco.mj_step = original_step
        rt.ctrl.update = original_update  # type: ignore[method-assign]
    n = min(len(ctrl_t), len(step_t))
    both = [a + b for a, b in zip(ctrl_t[:n], step_t[:n], strict=True)]
    return {
        "controller (both arms Cartesian + torso)": ctrl_t,
        "mj_step (kitchen scene)": step_t,
        "controller + mj_step": both,
        "Runtime.cycle (whole cycle)": cycle_t,
        "controller, all safety terms active": worst_t,
    }


def main() -> int:
    """Run the benchmark and print the tables; exit status 0 (figures are informative)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=5000)
    parser.add_argument("--warmup", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--law", choices=("compiled", "python", "both"), default="both")
    args = parser.parse_args()
    laws = ["compiled", "python"] if args.law == "both" else [args.law]
    if "compiled" in laws and not compiled_available():
        print("the compiled law is not built (no C++ compiler at install?): measuring the Python law only")
        laws = ["python"]
    print(describe())
    print(f"{args.cycles} timed cycles after {args.warmup} warm-up cycles, {args.repeats} repeat(s)\n")
    for law in laws:
        best_p99 = float("inf")
        for r in range(args.repeats):
            load_before = load()
            rows = run(args.cycles, args.warmup, law)
            print(f"{law} law, repeat {r + 1} (load average before {load_before}, after {load()})")
            print(f"  {'':44s} {'p50 µs':>8s} {'p99 µs':>8s} {'max µs':>9s}")
            for name, seconds in rows.items():
                p50, p99, worst = stats(seconds)
                print(f"  {name:44s} {p50:8.1f} {p99:8.1f} {worst:9.1f}")
            best_p99 = min(best_p99, stats(rows["controller (both arms Cartesian + torso)"])[1])
            print()
        verdict = "meets" if best_p99 <= TARGET_P99_US else "misses"
        print(
            f"{law} law: controller p99, best repeat: {best_p99:.1f} µs "
            f"({verdict} the {TARGET_P99_US:.0f} µs target)\n"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
