"""``roco up`` and ``roco down``: a fleet on this machine that keeps running until stopped
(services/fleet/launcher.py), and the compose fleet's end (``roco down --compose``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli_common import (
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
    fleet_endpoint,
    fleet_state,
    new_run_folder,
    port_free,
    security_switches,
    stop_on_signals,
)
from services.fleet.launcher import GATEWAY, ROS2, Fleet, LaunchError, spec_env
from services.fleet.processes import stop_pids
from services.fleet_state import FLEET_FILE, FleetState, write_state
from services.ros2.live_cli import ros2_args
from services.runtime.run_folder import RunInfo, write_run_info
from services.runtime.session import SessionRefused, open_client, open_operator
from services.scenario.run_env import scene_env, viewer_env
from services.spec.model import load
from services.spec_check.report_cli import fleet_end
from shared.settings import ROUTER_PORT, Settings

if TYPE_CHECKING:
    import zenoh

control_app = typer.Typer()


@control_app.command(short_help="Start a fleet that keeps running: router, recorder, agents.")
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
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{port}", env=env)
    info.router = endpoint = fleet.endpoint  # tls/… when the router listens on TLS
    write_run_info(run_dir, info)
    session: zenoh.Session | None = None
    try:
        fleet.start_router()
        session = open_client(endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        fleet.start_agents()
        waited = fleet.wait_alive(session, fleet.agents, timeout=120)
        served = _start_faces(fleet, session, gateway, face)
    except (LaunchError, KeyboardInterrupt) as exc:
        if session is not None:
            session.close()
        fleet.stop()
        why = "interrupted" if isinstance(exc, KeyboardInterrupt) else str(exc)
        info.processes = fleet.pids()
        write_run_info(run_dir, info)
        fleet_end(run_dir, failure=why)
        code = INTERRUPTED if isinstance(exc, KeyboardInterrupt) else 1
        raise fail(f"{why}; nothing of the fleet is left running; run folder {run_dir}", code) from None
    session.close()
    info.processes = fleet.pids()
    write_run_info(run_dir, info)
    write_state(runs_dir, FleetState(endpoint, str(run_dir), fleet.pids()))
    typer.echo(f"roco: fleet up on {endpoint} in {waited:.1f} s{served}; run folder {run_dir}")


def _start_faces(
    fleet: Fleet, session: zenoh.Session, gateway: int | None, ros2: tuple[str, ...] | None
) -> str:
    """Start the ACL gateway on port ``gateway`` (None: none) and the ROS 2 face (``roco ros2``
    with the arguments ``ros2``; None: none) and wait for their tokens; the tail of `roco up`'s
    line that names them. Raises LaunchError."""
    served = ""
    if gateway is not None:
        fleet.start_gateway(gateway)
        fleet.wait_alive(session, [GATEWAY], timeout=60)
        served += f"; gateway http://127.0.0.1:{gateway}/acc"
    if ros2 is not None:
        fleet.start_ros2(ros2)
        fleet.wait_alive(session, [ROS2], timeout=60)
        served += f"; ROS 2 node /roco (roco ros2 {' '.join(ros2)})"
    return served


@control_app.command(short_help="Stop the fleet that roco up started and write its report.")
def down(
    runs_dir: Annotated[
        Path, typer.Option("--runs-dir", help="where 'roco up' keeps the state of the fleet to stop")
    ] = Path("runs"),
    compose: Annotated[
        bool, typer.Option("--compose", help="stop the compose fleet (docs/deploy.md) and write its report")
    ] = False,
    project: Annotated[
        str | None,
        typer.Option(help="compose: the project [default: $ROCO_COMPOSE_PROJECT, else the one running]"),
    ] = None,
    compose_file: Annotated[
        Path | None, typer.Option(help="compose: the compose file [default: the running fleet's]")
    ] = None,
    volumes: Annotated[
        bool, typer.Option("--volumes", "-v", help="compose: delete the named volumes too (down -v)")
    ] = False,
    router: Annotated[
        str, typer.Option(help="compose: the router, for the agents' counters")
    ] = f"tls/127.0.0.1:{ROUTER_PORT}",
    credentials: Annotated[
        Path | None,
        typer.Option(
            help="compose: the operator's credentials [default: deploy/certs beside the compose file]"
        ),
    ] = None,
    spec: SpecFile = None,
) -> None:
    """Stop the fleet `roco up` started (only the processes it started, by PID), naming each
    as it stops: the agents (their counters kept first: what they raised is said and in the
    report), the recorder once it confirmed the traffic record complete, the router. Then
    record in the run's run.json the commands the fleet was given and their outcomes (from its
    C2 traffic) and write its report. A fleet of `roco hosts up` is
    stopped as `roco hosts down` does.

    With --compose, the compose fleet: its agents' counters kept (when the router answers
    with the operator's credentials), `docker compose down` (or `docker-compose`), then
    run.json and the report of its run folder on the host, as above (writing there needs the
    right to: the containers make its files as root). The agents asked for their counters are
    those of --spec, else of the specification the run used, else of the shipped one."""
    from services.hosts.cli import HOSTS_FILE
    from services.hosts.cli import down as hosts_down
    from services.recorder.sync import sync_fleet, sync_words

    if compose:
        _compose_down(project, compose_file, volumes, router, credentials, spec)
        return
    if (runs_dir / HOSTS_FILE).exists():
        hosts_down(runs_dir)
        return
    state = fleet_state(runs_dir)
    if state is None:
        raise fail(f"no fleet is up (no {runs_dir / FLEET_FILE})")
    raised = _save_fleet_counters(state, spec)
    typer.echo("roco: stopping", nl=False)
    _stop({n: p for n, p in state.pids.items() if n not in ("recorder", "router")})
    # everything the agents sent before they stopped is in the traffic record before it closes
    if "recorder" in state.pids:
        synced = sync_fleet(state.endpoint, Path(state.run_dir) / "security")
        typer.echo(f"; recorder: {sync_words(synced)}", nl=False)
        _stop({"recorder": state.pids["recorder"]}, named=False)
    if "router" in state.pids:
        typer.echo("; router", nl=False)
        _stop({"router": state.pids["router"]}, named=False)
    typer.echo("")
    (runs_dir / FLEET_FILE).unlink()
    typer.echo(f"roco: fleet stopped {fleet_end(Path(state.run_dir))}")
    if raised:
        typer.echo(f"roco: agents raised: {raised}")


def _compose_target(project: str | None, file: Path | None) -> tuple[str, Path]:
    """The compose fleet `roco down --compose` stops: ``project`` (else ``ROCO_COMPOSE_PROJECT``,
    else the one running) and its compose ``file`` (else the running fleet's, else the
    project's deploy/compose.yaml); exit 2 when no fleet, or several, run and none is named."""
    from services.deploy import engine
    from services.deploy.compose import COMPOSE_FILE

    project = project or Settings.from_env(only=("compose_project",)).compose_project
    if project is not None:
        return project, file or COMPOSE_FILE
    fleets = engine.running_fleets(engine.run_command)
    if len(fleets) != 1:
        running = ", ".join(f.project for f in fleets)
        which = f"compose fleets {running} run" if fleets else "no compose fleet runs"
        raise fail(f"{which}: say which with --project NAME", code=2)
    return fleets[0].project, file or fleets[0].file() or COMPOSE_FILE


def _compose_down(
    project: str | None,
    file: Path | None,
    volumes: bool,
    router: str,
    credentials: Path | None,
    spec: Path | None = None,
) -> None:
    """`roco down --compose`: find the fleet (services/deploy/engine.py), keep its agents'
    counters, stop it, then conclude its run folder and write the report
    (services/spec_check/report_cli.py ``fleet_end``); one line and exit 1 (2 for a choice to
    make) when any step cannot be done."""
    from services.deploy import engine

    project, file = _compose_target(project, file)
    try:
        base = engine.base_command(file, project, engine.run_command)
        name = engine.run_name(base, engine.run_command)
        runs = engine.runs_folder(base, engine.run_command)
        run_dir = runs / name if runs is not None and name is not None else None
        agents = load(chosen_spec(spec, run_dir)).agent_names
        kept = _save_compose_counters(router, credentials or file.parent / "certs", run_dir, agents)
        engine.down(base, volumes, engine.run_command)
    except engine.ComposeFailed as exc:
        raise fail(str(exc)) from None
    typer.echo(f"roco: compose project {project} stopped{kept}")
    if run_dir is None:
        raise fail(f"no report: the run of compose project {project} is not known (was it running?)")
    ended = fleet_end(run_dir)
    typer.echo(f"roco: run {run_dir} {ended}")
    if "report not written" in ended:
        raise typer.Exit(1)


def _save_compose_counters(
    router: str, credentials: Path, run_dir: Path | None, agents: tuple[str, ...]
) -> str:
    """Keep the counters of a compose fleet's ``agents`` in its run folder (the report's
    "Agents raised"); the words that say whether they were kept."""
    from services.runtime.counters import ask_counters, save_counters

    if run_dir is None:
        return ""
    try:
        session = open_operator(router, credentials=credentials if credentials.is_dir() else None)
    except SessionRefused as exc:
        return f" (agents' counters not kept: {exc})"
    try:
        counters = ask_counters(session, agents, timeout=5.0)
    finally:
        session.close()
    try:
        save_counters(run_dir, counters)
    except OSError as exc:
        return f" (agents' counters not kept: {exc.strerror or exc})"
    return f" (counters of {', '.join(sorted(counters)) or 'no agent'} kept)"


def _save_fleet_counters(state: FleetState, spec: Path | None = None) -> str:
    """Before `roco down` stops a fleet: its agents' counters into the run folder's
    counters.json (the report's "Agents raised" reads them) and what they raised, in words
    (services/runtime/raised.py; "" when nothing). Nothing is saved when no router answers."""
    from services.runtime.counters import ask_counters, save_counters
    from services.runtime.raised import raised_by_agent, raised_text

    try:
        session = open_operator(fleet_endpoint(state))
    except SessionRefused:
        return ""
    try:
        agents = load(chosen_spec(spec, Path(state.run_dir))).agent_names
        counters = ask_counters(session, [n for n in state.pids if n in agents], timeout=5.0)
    finally:
        session.close()
    save_counters(Path(state.run_dir), counters)
    return raised_text(raised_by_agent({a: r.counters for a, r in counters.items()}), {})


def _stop(pids: dict[str, int], *, named: bool = True) -> None:
    """Stop the processes of ``pids`` (services/fleet/processes.py ``stop_pids``), naming each
    (``named``) as it ends on the current line, and each one killed after the grace period."""

    def ended(name: str, killed: bool) -> None:
        if killed:
            typer.echo(f" {name} (killed)", nl=False)
        elif named:
            typer.echo(f" {name}", nl=False)

    stop_pids(pids, on_end=ended)
