"""What ``roco run``, ``scenario``, ``chaos`` and ``up`` set up before a fleet starts: the
specification it runs, the perception check, the scene's environment, Rerun recording and
viewer, the live view (services/cli/run.py, scenario.py, chaos.py, up.py)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from services.cli.common import chosen_spec, fail
from shared.settings import Settings

if TYPE_CHECKING:
    from services.live.watch import LiveWatch
    from services.spec.model import SystemSpec


def live_watch(title: str, live: bool | None, quiet: bool, system: SystemSpec) -> LiveWatch | None:
    """The live view (services/live/) of a fleet of ``system`` when asked, or by default when
    stdout is a terminal and not ``quiet``; None: plain lines."""
    from rich.console import Console

    from services.live.watch import LiveWatch
    from services.spec.notices import notice_protocols

    console = Console(highlight=False)
    if live is False or (live is None and (quiet or not console.is_terminal)):
        return None
    return LiveWatch(title, system.launch_order, console=console, notice_protocols=notice_protocols(system))


def kitchen_spec(given: Path | None, command: str, why: str) -> Path:
    """The specification ``command`` runs: ``given`` (``--spec``, ``ROCO_SPEC``), else the
    shipped one (services/cli/common.py ``chosen_spec``). One line and exit 2 when it is
    another system than the kitchen (services/scenario/model.py ``missing_kitchen_agents``),
    saying ``why`` ``command`` needs the kitchen."""
    from services.scenario.model import missing_kitchen_agents
    from services.spec.model import load

    path = chosen_spec(given)
    system = load(path)
    missing = missing_kitchen_agents(system)
    if missing:
        raise fail(
            f"{command} {why}: {system.system} ({path}) has no {', '.join(missing)}; "
            "run it with roco run --spec, or roco up --spec and roco send",
            code=2,
        )
    return path


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
