"""``roco down``: stop the fleet ``roco up`` (or ``roco hosts up``) started, or the compose fleet
(``--compose``), and write its report (services/control/stop.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import SpecFile, chosen_spec, fail, fleet_endpoint, fleet_state
from services.fleet.processes import stop_pids
from services.fleet_state import FLEET_FILE
from services.spec.model import load
from shared.settings import ROUTER_PORT

down_app = typer.Typer()


@down_app.command(short_help="Stop the fleet that roco up started and write its report.")
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
    from services.cli.hosts import down as hosts_down
    from services.control.stop import keep_fleet_counters
    from services.hosts.state import HOSTS_FILE
    from services.recorder.sync import sync_fleet, sync_words
    from services.spec_check.run_report import fleet_end

    if compose:
        _compose_down(project, compose_file, volumes, router, credentials, spec)
        return
    if (runs_dir / HOSTS_FILE).exists():
        hosts_down(runs_dir)
        return
    state = fleet_state(runs_dir)
    if state is None:
        raise fail(f"no fleet is up (no {runs_dir / FLEET_FILE})")
    run_dir = Path(state.run_dir)
    raised = keep_fleet_counters(
        fleet_endpoint(state), run_dir, state.pids, lambda: load(chosen_spec(spec, run_dir)).agent_names
    )
    typer.echo("roco: stopping", nl=False)
    _stop({n: p for n, p in state.pids.items() if n not in ("recorder", "router")})
    # everything the agents sent before they stopped is in the traffic record before it closes
    if "recorder" in state.pids:
        synced = sync_fleet(state.endpoint, run_dir / "security")
        typer.echo(f"; recorder: {sync_words(synced)}", nl=False)
        _stop({"recorder": state.pids["recorder"]}, named=False)
    if "router" in state.pids:
        typer.echo("; router", nl=False)
        _stop({"router": state.pids["router"]}, named=False)
    typer.echo("")
    (runs_dir / FLEET_FILE).unlink()
    typer.echo(f"roco: fleet stopped {fleet_end(run_dir)}")
    if raised:
        typer.echo(f"roco: agents raised: {raised}")


def _compose_down(
    project: str | None,
    file: Path | None,
    volumes: bool,
    router: str,
    credentials: Path | None,
    spec: Path | None = None,
) -> None:
    """`roco down --compose`: find the fleet, keep its agents' counters, stop it
    (services/control/stop.py), then conclude its run folder and write the report
    (services/spec_check/run_report.py ``fleet_end``); one line and exit 1 (2 for a choice to
    make) when any step cannot be done."""
    from services.control.stop import NoComposeFleet, compose_target, stop_compose
    from services.deploy.engine import ComposeFailed
    from services.spec_check.run_report import fleet_end

    try:
        project, file = compose_target(project, file)
    except NoComposeFleet as exc:
        raise fail(str(exc), code=2) from None
    try:
        stopped = stop_compose(
            project, file, volumes, router, credentials, lambda run: load(chosen_spec(spec, run)).agent_names
        )
    except ComposeFailed as exc:
        raise fail(str(exc)) from None
    typer.echo(f"roco: compose project {project} stopped{stopped.kept}")
    if stopped.run_dir is None:
        raise fail(f"no report: the run of compose project {project} is not known (was it running?)")
    ended = fleet_end(stopped.run_dir)
    typer.echo(f"roco: run {stopped.run_dir} {ended}")
    if "report not written" in ended:
        raise typer.Exit(1)


def _stop(pids: dict[str, int], *, named: bool = True) -> None:
    """Stop the processes of ``pids`` (services/fleet/processes.py ``stop_pids``), naming each
    (``named``) as it ends on the current line, and each one killed after the grace period."""

    def ended(name: str, killed: bool) -> None:
        if killed:
            typer.echo(f" {name} (killed)", nl=False)
        elif named:
            typer.echo(f" {name}", nl=False)

    stop_pids(pids, on_end=ended)
