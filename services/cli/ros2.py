"""``roco ros2``: a live ROS 2 face on the fleet's own Zenoh (services/ros2/live.py), and the
arguments of the face that ``roco run``, ``scenario`` and ``up`` start with ``--ros2``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import FleetRunsDir, RouterOption, SpecFile, endpoint_of, fail, fleet_spec

ros2_app = typer.Typer()


def ros2_args(on: bool, domain: int, namespace: str) -> tuple[str, ...] | None:
    """The arguments of ``roco ros2`` for ``--ros2`` (``--all`` on ``domain`` in ``namespace``);
    None without ``--ros2``. A bad namespace is one ``roco:`` line (exit 2) before anything
    starts."""
    if not on:
        return None
    _require_extra()
    if namespace != "/":
        from services.ros2.rmw import RmwError, fully_qualified

        try:
            fully_qualified(namespace)
        except RmwError as exc:
            raise fail(f"--ros2-namespace: {exc}", 2) from None
    return ("--all", "--domain", str(domain), "--namespace", namespace)


@ros2_app.command(short_help="A ROS 2 node on the fleet's Zenoh (rmw_zenoh's wire format).")
def ros2(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    domain: Annotated[int, typer.Option(min=0, max=232, help="ROS_DOMAIN_ID")] = 0,
    namespace: Annotated[str, typer.Option(help="the node's namespace")] = "/",
    joint_states: Annotated[bool, typer.Option("--joint-states", help="publish joint_states")] = False,
    tf: Annotated[bool, typer.Option("--tf", help="publish tf (the links' world poses)")] = False,
    task_state: Annotated[bool, typer.Option("--task-state", help="publish roco/task_state")] = False,
    camera: Annotated[
        bool,
        typer.Option("--camera", help="publish the head camera (image_raw, camera_info)"),
    ] = False,
    all_topics: Annotated[bool, typer.Option("--all", help="publish every topic above")] = False,
    say: Annotated[bool, typer.Option(help="serve roco/say (a person's sentence to a_hi)")] = True,
    spec: SpecFile = None,
    write_package: Annotated[
        Path | None,
        typer.Option("--write-package", help="write ROS 2 package roco_msgs into this new folder; exit"),
    ] = None,
) -> None:
    """Be ROS 2 node /roco on the fleet's own Zenoh, in rmw_zenoh's wire format (key
    expressions, CDR, attachments, liveliness tokens): publish the topics asked for (nothing
    unless asked; ag_ex renders the camera's images only while a ROS 2 node subscribes) and
    serve roco/say (roco_msgs/srv/Say): a sentence, checked against the specification's
    external role x_ros2 (C9 to a_hi), answered with a_hi's outcome; progress on
    roco/say/progress. A malformed or out-of-protocol call is refused and counted (roco
    status). Runs until Ctrl-C (docs/ros2.md). With --write-package DIR: writes roco's own
    interfaces as the ROS 2 package roco_msgs (for colcon build) and exits."""
    if write_package is not None:
        _write_package(write_package)
        return
    _require_extra()
    from services.ros2.face import CAMERA, JOINT_STATES, TASK_STATE, TF, TOPICS, FaceConfig
    from services.ros2.live import LiveConfig
    from services.ros2.live import main as run_live

    asked = {JOINT_STATES: joint_states, TF: tf, TASK_STATE: task_state, CAMERA: camera}
    topics = frozenset(TOPICS) if all_topics else frozenset(t for t, on in asked.items() if on)
    face = FaceConfig(domain=domain, namespace=namespace, topics=topics, say=say)
    code = run_live(LiveConfig(endpoint_of(router, runs_dir), face, fleet_spec(spec, runs_dir, router)))
    if code:
        raise typer.Exit(code)


def _require_extra() -> None:
    """One ``roco:`` line (exit 2) when the ros2 extra the face needs is not installed."""
    from services.ros2.messages import missing_extra

    problem = missing_extra()
    if problem is not None:
        raise fail(problem, 2)


def _write_package(out: Path) -> None:
    from services.cli.common import fail
    from services.ros2.package import write_package

    try:
        written = write_package(out)
    except OSError as exc:  # FileExistsError: a folder that holds something
        raise fail(str(exc)) from None
    typer.echo(f"roco: roco_msgs ({len(written)} files) in {out}: colcon build it in a ROS 2 workspace")
