"""Benchmark of the world's checkpoints (velma/executor/checkpoint.py): what the 1 kHz loop
pays once per second, how big a checkpoint is, what writing and restoring cost.

Builds ``Runtime(seed=0)`` (the kitchen, 18 content spheres), runs the left arm's grasp of the
jar and half its lift (as tests/velma/test_checkpoint.py), freezes the garbage collector as the
loop process does, then times with ``time.perf_counter`` over ``--samples`` calls each:

- ``mj_getState``: MuJoCo's integration state into the preallocated array;
- ``Capture.take``: that, plus the controllers' state into the preallocated layout, plus the
  msgpack encoding of the ``Checkpoint``;
- ``publish (in the loop)``: ``LoopCheckpoints.publish``: ``take`` plus the write into the
  shared-memory block, i.e. what one loop cycle in 1000 pays;
- ``write_atomic (comm side)``: the communication side's file write (tmp, fsync, replace);
- ``restore (at start)``: ``decode`` + ``apply`` + ``resume`` into a second Runtime.

Prints wall-time p50 / p99 / max and the thread's CPU time p50 / p99 (``time.thread_time_ns``:
what the call costs without the time other processes took the CPU away) in µs, and the
checkpoint's size, with the machine it ran on.

Usage: ``python scripts/bench_checkpoint.py [--samples 5000] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import gc
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import benchlib  # scripts/benchlib.py, beside this file
import mujoco
import numpy as np

from shared.fipa_codec.languages.l_ex import Observe
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor import checkpoint as ck
from velma.executor.handoff import LatestValue
from velma.executor.loop import ControlLoop
from velma.executor.runtime import Runtime
from velma.scenario import script_poses

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' grasp, in tests/support
from tests.support.grasp import left_jar_grasp, left_jar_lift


def _run(loop: ControlLoop[int], command: object) -> object:
    loop.submit(0, command)  # type: ignore[arg-type]
    while (done := loop.cycle()) is None:
        pass
    return done[1]


def holding_the_jar() -> tuple[Runtime, ControlLoop[int]]:
    rt = Runtime(seed=0)
    rt.observe_by_camera = False  # the ground truth's poses: this benchmark is about checkpoints
    loop: ControlLoop[int] = ControlLoop(rt)
    obs = _run(loop, Observe())
    assert isinstance(obs, Observation)
    poses = script_poses(obs)
    for command in left_jar_grasp(poses):
        _run(loop, command)
    loop.submit(1, left_jar_lift(poses))
    for _ in range(1000):
        loop.cycle()
    return rt, loop


def timed(fn: Callable[[], object], samples: int) -> tuple[float, float, float, float, float]:
    """Wall time p50, p99, max and CPU time of this thread p50, p99 (µs) per call."""
    wall = np.empty(samples)
    cpu = np.empty(samples)
    for i in range(samples):
        c0 = time.thread_time_ns()
        t0 = time.perf_counter()
        fn()
        wall[i] = time.perf_counter() - t0
        cpu[i] = (time.thread_time_ns() - c0) * 1e-9
    p50, p99 = np.percentile(wall, [50, 99])
    c50, c99 = np.percentile(cpu, [50, 99])
    return float(p50) * 1e6, float(p99) * 1e6, float(wall.max()) * 1e6, float(c50) * 1e6, float(c99) * 1e6


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--samples", type=int, default=5000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(benchlib.machine(("mujoco", "numpy", "msgspec")))
    rt, loop = holding_the_jar()
    print(f"world: sim time {rt.time:.3f} s, left hand holds {rt.model.body(rt.held['left']).name}")
    block = LatestValue.create(ck.CHECKPOINT_CAPACITY)
    with tempfile.TemporaryDirectory() as tmp:
        keeper = ck.LoopCheckpoints(Path(tmp), ck.DirLock(Path(tmp)), ck.Capture(rt), block)
        raw = keeper.capture.take(loop.holding)
        print(
            f"checkpoint: {len(raw)} B (physics {8 * keeper.capture.fp.nstate} B = "
            f"mjSTATE_INTEGRATION of nq {rt.model.nq}, nv {rt.model.nv}, nu {rt.model.nu}, "
            f"nbody {rt.model.nbody}; controllers {8 * keeper.capture.controller.size} B)"
        )
        back = Runtime(seed=0)
        again: ControlLoop[int] = ControlLoop(back)
        fp = ck.fingerprint(back.model)

        def restore() -> None:
            ckpt = ck.decode(raw, fp)
            ck.apply(back, ckpt)
            ck.resume(again, ckpt)

        path = Path(tmp) / ck.FILE_NAME
        gc.collect()
        gc.freeze()
        cases: list[tuple[str, Callable[[], object], int]] = [
            (
                "mj_getState",
                lambda: mujoco.mj_getState(rt.model, rt.data, keeper.capture.physics, keeper.capture.sig),
                args.samples,
            ),
            ("Capture.take", lambda: keeper.capture.take(loop.holding), args.samples),
            ("publish (in the loop)", lambda: keeper.publish(loop.holding), args.samples),
            ("write_atomic (comm side)", lambda: ck.write_atomic(path, raw), max(50, args.samples // 50)),
            ("restore (at start)", restore, max(50, args.samples // 50)),
        ]
        for r in range(args.repeats):
            print(
                f"repeat {r + 1}: {'wall p50':>33s} {'p99':>9s} {'max':>9s} {'CPU p50':>9s} {'p99':>9s}  (µs)"
            )
            for name, fn, n in cases:
                p50, p99, worst, c50, c99 = timed(fn, n)
                print(f"  {name:26s} {p50:9.1f} {p99:9.1f} {worst:9.1f} {c50:9.1f} {c99:9.1f}  ({n} calls)")
    block.close()
    block.unlink()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
