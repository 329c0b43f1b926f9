"""``python -m velma.world``: Velma's hardware side in the simulated kitchen as a process of its
own (velma/world/serve.py), the way a real robot exists beside its controller.

It makes the robot link and writes the link's name to ``RUN/world.link`` (velma/world/files.py
``LINK_FILE``, written whole: a reader sees the old name or the new one), where a controller
finds it (``link_name``); it serves until SIGTERM or SIGINT, then writes the kitchen as it is
then to ``RUN/world_final.f64`` (``FINAL_FILE``: the time and MuJoCo's ``qpos`` as raw float64,
for judging the run, e.g. by ``roco chaos``) and removes the link and its file. Once it serves
the link it says so on stdout and writes ``ROCO_READY_FILE`` (shared/ready_file.py: a
container's health check reads it), which it removes when it stops.
Settings come from the options, else from the fleet's environment: ``--run-dir``
(``ROCO_RUN_DIR``), ``--realtime`` (``ROCO_REALTIME=1``), ``--seed`` (``ROCO_SEED``: the jar's
content jitter), ``--pose-seed`` (``ROCO_POSE_SEED``: the jar's and the bowl's poses); from the
environment only, ``ROCO_CONTENT_REMOVED`` (spheres taken out of the jar before the start,
velma/model/scene.py ``remove_content``). A bad option, setting or a run folder that does not
exist: one line on stderr, exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
from pathlib import Path
from types import FrameType

import numpy as np

from shared.ready_file import clear as clear_ready
from shared.ready_file import mark as mark_ready
from shared.settings import Settings
from velma.realtime import WORLD_FIFO_PRIORITY, enter_realtime
from velma.shm import remove_orphans
from velma.world.files import FINAL_FILE, LINK_FILE, link_name, write_whole
from velma.world.hardware import SimulatedVelma
from velma.world.layout import COMMAND, MEASURED
from velma.world.link import RobotLink
from velma.world.serve import serve


def _parser() -> argparse.ArgumentParser:
    read = Settings.from_env(only=("run_dir", "realtime"))
    ap = argparse.ArgumentParser(prog="python -m velma.world", description=__doc__.splitlines()[0])
    ap.add_argument("--run-dir", type=Path, default=read.run_dir, help="the run folder")
    ap.add_argument(
        "--realtime",
        action=argparse.BooleanOptionalAction,
        default=read.realtime,
        help="step on the wall clock (default: in lockstep with the controller)",
    )
    ap.add_argument("--seed", type=int, default=None, help="the jar's content jitter (ROCO_SEED, 0)")
    ap.add_argument("--pose-seed", type=int, default=None, help="random jar and bowl poses (ROCO_POSE_SEED)")
    return ap


def _inputs(args: argparse.Namespace) -> tuple[int, int | None, Path, int]:
    """The seeds (the options', else the environment's), the run folder of ``args`` and the
    spheres removed (the environment's). Raises ValueError for a seed or count that is not an
    integer ≥ 0 or a run folder that is not one."""
    unset = [f for f, given in (("seed", args.seed), ("pose_seed", args.pose_seed)) if given is None]
    read = Settings.from_env(only=[*unset, "content_removed"])
    seed = args.seed if args.seed is not None else read.seed
    pose_seed = args.pose_seed if args.pose_seed is not None else read.pose_seed
    run_dir: Path | None = args.run_dir
    if run_dir is None or not Path(run_dir).is_dir():
        raise ValueError(f"no run folder {run_dir or '(give --run-dir or ROCO_RUN_DIR)'}")
    return seed, pose_seed, Path(run_dir), read.content_removed


def _realtime_setup() -> str:
    """Ask for SCHED_FIFO at ``WORLD_FIFO_PRIORITY`` on the lowest-numbered CPU this process may
    use (ag_ex's loop takes the highest; docs/executor.md "Pacing" measures both placements):
    one line saying what the OS granted, and why not what it refused."""
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else [0]
    setup = enter_realtime(priority=WORLD_FIFO_PRIORITY, cpu=cpus[0], cpu_latency_us=None)
    return "; ".join([setup.describe(), *setup.notes])


def main(argv: list[str] | None = None) -> int:
    """Run the world (module docstring); the exit code."""
    args = _parser().parse_args(argv)
    try:
        seed, pose_seed, run_dir, removed = _inputs(args)
    except ValueError as exc:
        print(f"velma.world: {exc}", file=sys.stderr)
        return 2
    ready = Settings.from_env(only=("ready_file",)).ready_file
    clear_ready(ready)  # a file a killed world left does not speak for this one
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    remove_orphans()  # the blocks of a world that was killed
    try:
        sim = SimulatedVelma(seed=seed, pose_seed=pose_seed, removed=removed)
    except ValueError as exc:  # more spheres removed than the jar holds
        print(f"velma.world: {exc}", file=sys.stderr)
        return 2
    link = RobotLink.create(MEASURED.size, COMMAND.size, sim.scene_size)
    named = run_dir / LINK_FILE
    try:
        write_whole(named, (link.name + "\n").encode())
        serving = f"velma.world: serving the robot link {link.name} ({named})"
        print(serving, flush=True)
        if (why := mark_ready(ready, serving)) is not None:
            print(f"velma.world: {why}", file=sys.stderr, flush=True)
        if args.realtime:  # the robot's hardware side keeps its schedule (velma/realtime.py)
            print(f"velma.world: {_realtime_setup()}", flush=True)
        serve(sim, link, realtime=args.realtime, should_stop=stop.is_set)
        final = np.zeros(sim.scene_size)
        sim.scene(final)
        write_whole(run_dir / FINAL_FILE, final.tobytes())
    finally:
        clear_ready(ready)
        if link_name(run_dir) == link.name:
            with contextlib.suppress(FileNotFoundError):
                named.unlink()
        link.close()
    return 0
