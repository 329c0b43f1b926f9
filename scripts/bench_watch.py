"""The watch's costs: a watch frame beside an Observe, and the pace of a watched simulation.

1. Frames: the head camera's observer (velma/executor/observer.py ``CameraObserver``, 640 ×
   480, software GL where no GPU) observes the kitchen's initial state with the head aimed at
   the shelf (velma/scenario.py ``HEAD_LOOK_CABINET``) and at the table, ``--repeats`` times
   each, as an Observe (``FRAMES_AVERAGED`` frames, the jar, bowl and cup localised, their
   content counted, the spill counted) and as a watch frame (``WorldCapture.watch``: one frame
   of 320 × 240 px, localisation only). Printed: wall ms per observation (p50 / p95 / max), the
   renderers made beforehand, and the largest position error of an object seen (mm, against the
   physics: velma/executor/ground_truth.py).
2. Pace: ag_ex's executor with its loop in its own process, as fast as possible
   (``ExecutorProcess(realtime=False)``), runs ``Wait`` commands of ``--seconds`` robot s
   without a watch and with one (``ExecutorProcess.watch``, every ``--period`` robot s,
   paced to ROCO_WATCH_PACE × wall time): robot s per wall s, and the watch's frames made and
   skipped.

Usage: ``python scripts/bench_watch.py [--repeats 10] [--seconds 5] [--period 0.25]``
"""

from __future__ import annotations

import argparse
import queue
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from shared.fipa_codec.languages.l_ex import CommandResult, Wait  # noqa: E402
from shared.fipa_codec.languages.l_sd import Observation  # noqa: E402
from velma.executor import ExecutorProcess  # noqa: E402
from velma.executor.capture import WorldCapture  # noqa: E402
from velma.executor.ground_truth import GroundTruth  # noqa: E402
from velma.executor.observer import CameraObserver  # noqa: E402
from velma.model.scene import initial_state, load_kitchen  # noqa: E402
from velma.perception.kinect import aim_head  # noqa: E402
from velma.scenario import HEAD_LOOK_CABINET  # noqa: E402

OBJECTS = ("jar", "bowl", "cup")
TABLE_LOOK = (0.3, -0.65, 0.75)  # the table's top centre (kitchen.xml)


def _ms(values: list[float]) -> str:
    a = np.asarray(values)
    return f"{np.percentile(a, 50):.0f} / {np.percentile(a, 95):.0f} / {a.max():.0f}"


def frames(repeats: int) -> None:
    """Part 1 (module docstring)."""
    model = load_kitchen()
    data = initial_state(model)
    observer = CameraObserver(model)
    truth = GroundTruth(model)
    print("| head aimed at | observation | wall ms p50 / p95 / max | objects seen | largest error, mm |")
    print("|---|---|---|---|---|")
    try:
        for where, point in (("shelf", HEAD_LOOK_CABINET), ("table", TABLE_LOOK)):
            aim_head(model, data, np.asarray(point, dtype=float))
            mujoco.mj_forward(model, data)
            for kind, watch in (("Observe", False), ("watch frame", True)):
                capture = WorldCapture.of(OBJECTS, float(data.time), data.qpos, watch=watch)
                observer.observe(capture)  # the first one builds the renderer's buffers
                took: list[float] = []
                seen, worst = 0, 0.0
                for _ in range(repeats):
                    t0 = time.perf_counter()
                    obs, _ = observer.observe(capture)
                    took.append(1e3 * (time.perf_counter() - t0))
                    found = [o for o in obs.objects if o.name in OBJECTS]
                    seen = len(found)
                    for o in found:
                        true = truth.pose(data, o.name).position
                        worst = max(worst, 1e3 * float(np.linalg.norm(np.subtract(o.pose.position, true))))
                error = f"{worst:.1f}" if seen else "–"
                print(f"| {where} | {kind} | {_ms(took)} | {seen} of {len(OBJECTS)} | {error} |")
    finally:
        observer.close()


def pace(seconds: float, period: float) -> None:
    """Part 2 (module docstring)."""
    ex = ExecutorProcess(realtime=False, world_state=True, perception="camera")
    ex.start()
    try:
        print("\n| run | robot s | wall s | robot s per wall s | watch frames made / skipped |")
        print("|---|---|---|---|---|")
        for watched in (False, True):
            got: queue.SimpleQueue[Observation] = queue.SimpleQueue()
            if watched:
                ex.watch(OBJECTS, period, got.put)
            done: queue.SimpleQueue[CommandResult | Observation] = queue.SimpleQueue()
            ex.submit(Wait(duration=0.05), done.put)  # the watch's first frame, the camera warm
            done.get(timeout=300)
            t0, s0 = time.perf_counter(), _sim_time(ex)
            ex.submit(Wait(duration=seconds), done.put)
            done.get(timeout=600)
            wall, robot = time.perf_counter() - t0, _sim_time(ex) - s0
            made = ex.watch_counts
            counts = f"{made[0]} / {made[1]}" if made is not None else "–"
            run = "watched" if watched else "not watched"
            print(f"| {run} | {robot:.2f} | {wall:.2f} | {robot / wall:.2f} | {counts} |")
            if watched:
                ex.unwatch()
    finally:
        ex.stop()


def _sim_time(ex: ExecutorProcess) -> float:
    snap = ex.snapshot()
    return snap.sim_time if snap is not None else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10, help="observations of each kind and view")
    parser.add_argument("--seconds", type=float, default=5.0, help="robot s of each pace run")
    parser.add_argument("--period", type=float, default=0.25, help="the watch's period (robot s)")
    args = parser.parse_args()
    print(benchlib.header(("mujoco",)))
    frames(args.repeats)
    pace(args.seconds, args.period)


if __name__ == "__main__":
    main()
