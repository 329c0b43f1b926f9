"""What ``roco run``, ``scenario``, ``chaos`` and ``up`` set up before a fleet starts: the
perception check, the scene's environment, Rerun recording and viewer, the live view."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from services.cli_common import fail
from services.fleet.launcher import AGENT_ORDER
from shared.settings import Settings

if TYPE_CHECKING:
    from services.live.watch import LiveWatch


def live_watch(title: str, live: bool | None, quiet: bool) -> LiveWatch | None:
    """The live view (services/live/) when asked, or by default when stdout is a terminal and
    not ``quiet``; None: plain lines."""
    from rich.console import Console

    from services.live.watch import LiveWatch
    from services.spec.model import default_spec
    from services.spec.notices import notice_protocols

    console = Console(highlight=False)
    if live is False or (live is None and (quiet or not console.is_terminal)):
        return None
    return LiveWatch(title, AGENT_ORDER, console=console, notice_protocols=notice_protocols(default_spec()))


def check_perception() -> None:
    """Refuse a bad ``ROCO_PERCEPTION``, or ``camera`` where the head camera cannot render, with
    one line (exit 2); say once when the robot perceives with the ground truth because this
    machine has no off-screen GL library (velma/executor/capture.py ``perception_mode``)."""
    from velma.executor.capture import camera_unavailable, perception_mode

    try:
        perception_mode()
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    why = camera_unavailable()
    asked = Settings.from_env(only=("perception",)).perception
    if why is not None and asked == "camera":
        raise fail(f"{Settings.env_name('perception')}=camera, but {why}", code=2)
    if why is not None and asked is None:
        typer.echo(f"roco: the robot perceives with the physics' ground truth: {why}", err=True)


def scene_env(realtime: bool, seed: int, pose_seed: int | None) -> dict[str, str]:
    """The environment that tells ag_ex its pacing and scene (services/agents/executor/agent.py).
    Checks the perception first (``_check_perception``)."""
    check_perception()
    env = {Settings.env_name("realtime"): "1" if realtime else "0", Settings.env_name("seed"): str(seed)}
    if pose_seed is not None:
        env[Settings.env_name("pose_seed")] = str(pose_seed)
    return env


def viewer_env(record: bool, view: bool) -> dict[str, str]:
    """Rerun recording on or off for every process; with ``view``, a viewer started now that
    the fleet streams to as well (its URL printed)."""
    rerun = Settings.env_name("rerun")
    if not (record or view):
        return {rerun: "0"}
    env = {rerun: "1"}
    if view:
        from services.viewer.view import start_viewer

        try:
            viewer = start_viewer(None)
        except Exception as exc:  # the run goes on without the live view
            typer.echo(f"roco: no live viewer ({exc}); the run is still recorded", err=True)
            return env
        env[Settings.env_name("rerun_connect")] = viewer.grpc_url
        typer.echo(f"roco: Rerun viewer {viewer.web_url or 'opened'} (pid {viewer.pid})")
    return env
