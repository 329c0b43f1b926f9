"""``roco ros2``: a live ROS 2 face on the fleet's own Zenoh (services/ros2/live.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli_common import FleetRunsDir, RouterOption, endpoint_of

ros2_app = typer.Typer()


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
        typer.Option("--camera", help="publish head_camera/image_raw and head_camera/camera_info"),
    ] = False,
    all_topics: Annotated[bool, typer.Option("--all", help="publish every topic above")] = False,
    say: Annotated[bool, typer.Option(help="serve roco/say (a person's sentence to a_hi)")] = True,
    spec: Annotated[Path | None, typer.Option("--spec", help="a specification file")] = None,
) -> None:
    """Be ROS 2 node /roco on the fleet's own Zenoh, in rmw_zenoh's wire format (key
    expressions, CDR, attachments, liveliness tokens): publish the topics asked for (nothing
    unless asked; ag_ex renders the camera's images only while a ROS 2 node subscribes) and
    serve roco/say (roco_msgs/srv/Say): a sentence, checked against the specification's
    external role x_ros2 (C9 to a_hi), answered with a_hi's outcome; progress on
    roco/say/progress. A malformed or out-of-protocol call is refused and counted (roco
    status). Runs until Ctrl-C (docs/ros2.md)."""
    from services.ros2.face import CAMERA, JOINT_STATES, TASK_STATE, TF, TOPICS, FaceConfig
    from services.ros2.live import LiveConfig
    from services.ros2.live import main as run_live
    from services.spec.model import DEFAULT_SPEC

    asked = {JOINT_STATES: joint_states, TF: tf, TASK_STATE: task_state, CAMERA: camera}
    topics = frozenset(TOPICS) if all_topics else frozenset(t for t, on in asked.items() if on)
    face = FaceConfig(domain=domain, namespace=namespace, topics=topics, say=say)
    code = run_live(LiveConfig(endpoint_of(router, runs_dir), face, spec or DEFAULT_SPEC))
    if code:
        raise typer.Exit(code)
