"""``roco up``: a fleet on this machine that keeps running until ``roco down``
(services/control/start.py)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import (
    INTERRUPTED,
    AclOption,
    GatewayOption,
    Ros2DomainOption,
    Ros2NamespaceOption,
    Ros2Option,
    SpecFile,
    TlsOption,
    chosen_spec,
    fail,
    new_run_folder,
    port_free,
    security_switches,
    stop_on_signals,
)
from services.cli.ros2 import ros2_args
from services.cli.run_env import scene_env, viewer_env
from services.fleet.launcher import NotUp, spec_env
from services.fleet_state import FLEET_FILE
from services.runtime.run_folder import RunInfo
from shared.settings import ROUTER_PORT

up_app = typer.Typer()


@up_app.command(short_help="Start a fleet that keeps running: router, recorder, agents.")
def up(
    port: Annotated[int, typer.Option(min=1, max=65535, help="router TCP port on 127.0.0.1")] = ROUTER_PORT,
    runs_dir: Annotated[
        Path,
        typer.Option(
            "--runs-dir",
            help="where the fleet's run folder is made and its state kept for 'roco down', 'send', 'status'",
        ),
    ] = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = True,
    seed: Annotated[int, typer.Option(min=0, help="jitter of the jar content's start positions")] = 0,
    pose_seed: Annotated[
        int | None, typer.Option(min=0, help="randomise the jar and bowl poses (±2 cm, ±10°) with this seed")
    ] = None,
    record: Annotated[
        bool, typer.Option(help="record robot, scene and traffic in the run folder's recording.rrd (Rerun)")
    ] = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    gateway: GatewayOption = None,
    ros2: Ros2Option = False,
    ros2_domain: Ros2DomainOption = 0,
    ros2_namespace: Ros2NamespaceOption = "/",
    spec: SpecFile = None,
) -> None:
    """Start router, recorder and the agents of the specification (and the ACL gateway with
    `--gateway`, the ROS 2 face with `--ros2`) in the background; they keep running until
    `roco down`, which writes the run's report. The run folder keeps which specification it
    runs, so later commands on it need no --spec. A port in use, a specification that cannot
    be loaded, or a runs folder that cannot be written, is refused before anything starts; a
    fleet that does not come up is stopped (its report written)."""
    from services.control.start import start_fleet

    security_switches(acl, tls)
    system = chosen_spec(spec)
    state_file = runs_dir / FLEET_FILE
    if state_file.exists():
        raise fail(f"a fleet is already up ({state_file}); run 'roco down' first")
    port_free(port, "--port")
    face = ros2_args(ros2, ros2_domain, ros2_namespace)
    if gateway is not None:
        port_free(gateway, "--gateway")
    scene = scene_env(realtime, seed, pose_seed)
    run_dir = new_run_folder(runs_dir)
    env = scene | viewer_env(record, False) | spec_env(system)
    info = RunInfo(started=time.time(), realtime=realtime, seed=seed, pose_seed=pose_seed)
    stop_on_signals()
    try:
        started = start_fleet(run_dir, runs_dir, f"tcp/127.0.0.1:{port}", env, info, gateway, face)
    except NotUp as exc:
        code = INTERRUPTED if exc.interrupted else 1
        raise fail(f"{exc.why}; nothing of the fleet is left running; run folder {run_dir}", code) from None
    took = f"{started.waited:.1f} s{started.served}"
    typer.echo(f"roco: fleet up on {started.endpoint} in {took}; run folder {run_dir}")
