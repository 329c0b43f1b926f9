"""``roco export RUN --mcap [OUT]``: a run as a rosbag2 folder (services/ros2/export.py)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import SpecFile, chosen_spec, fail

export_app = typer.Typer()

DEFAULT_OUT = "rosbag2"
"""The bag folder's name inside the run folder when no OUT is given."""


@export_app.command(short_help="Export a run as a rosbag2 MCAP folder (ROS 2 types, CDR).")
def export(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")],
    out: Annotated[
        Path | None,
        typer.Argument(metavar="[OUT]", help="the bag folder to make [default: RUN/rosbag2]"),
    ] = None,
    mcap: Annotated[bool, typer.Option("--mcap", help="as a rosbag2 folder with one MCAP file")] = False,
    spec: SpecFile = None,
) -> None:
    """Write RUN as a rosbag2 folder (metadata.yaml and one MCAP file, profile ros2, CDR) that
    Foxglove, rosbags or `ros2 bag` read without roco: the robot's state from the run's
    recording.rrd (/joint_states, /tf, /tf_static, the wrist wrenches, the head camera's
    images and camera info; robot time as stamps) and every communicate on /roco/traffic as
    roco_msgs/msg/Communicate, its content as the JSON of its term in the content languages of
    the run's specification (--spec, else the one the run used). `roco spec verify` and `roco
    report` take the folder. Exit 2 when RUN is no run folder, OUT is taken, or the ros2 extra
    is missing."""
    from services.ros2.messages import MissingExtra
    from services.spec.model import load

    if not mcap:
        raise fail("say the format: roco export RUN --mcap [OUT] (the one format so far)", code=2)
    load(chosen_spec(spec, run_dir))  # registers the system's content languages
    try:
        from services.ros2.export import ExportError, export_run
    except ImportError as exc:  # pragma: no cover - the core dependencies are installed
        raise fail(f"roco export needs the ros2 extra ({exc})", code=2) from None
    target = out if out is not None else run_dir / DEFAULT_OUT
    started = time.perf_counter()
    try:
        done = export_run(run_dir, target)
    except (ExportError, MissingExtra) as exc:
        raise fail(str(exc), code=2) from None
    except OSError as exc:
        raise fail(f"cannot write {target}: {exc.strerror or exc}") from None
    for note in done.notes:
        typer.echo(f"note: {note}")
    for topic, count in done.counts.items():
        typer.echo(f"{topic:28} {done.types[topic]:34} {count:6}")
    typer.echo(
        f"roco: {done.messages} messages on {len(done.counts)} topics in {done.out} "
        f"({time.perf_counter() - started:.1f} s)"
    )
