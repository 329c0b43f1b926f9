"""``roco scenario``: a scripted session (services/scenario/model.py), each command's outcome
checked, run as ``roco run`` runs one command (services/cli/run.py). The scenarios are the
kitchen's, so the kitchen only."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import (
    AclOption,
    GatewayOption,
    LiveOption,
    RecordOption,
    Ros2DomainOption,
    Ros2NamespaceOption,
    Ros2Option,
    RunsDirMade,
    SpecFile,
    TlsOption,
    ViewOption,
    fail,
    security_switches,
)
from services.cli.ros2 import ros2_args
from services.cli.run import run_scenario
from services.cli.run_env import kitchen_spec, live_watch
from services.spec.model import load

scenario_app = typer.Typer()


@scenario_app.command(short_help="Run a scripted session and check every command's outcome.")
def scenario(
    name: Annotated[
        str | None, typer.Argument(help="a scenario file, or the name of one in the library")
    ] = None,
    runs_dir: RunsDirMade = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    quiet: Annotated[bool, typer.Option(help="print only the outcome")] = False,
    list_: Annotated[bool, typer.Option("--list", help="list the library's scenarios")] = False,
    record: RecordOption = True,
    view: ViewOption = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    live: LiveOption = None,
    gateway: GatewayOption = None,
    ros2: Ros2Option = False,
    ros2_domain: Ros2DomainOption = 0,
    ros2_namespace: Ros2NamespaceOption = "/",
    spec: SpecFile = None,
) -> None:
    """Run a scenario (several commands, interruptions, disturbances, restarts; see
    services/scenario/model.py) headless, check every command's outcome against what the
    scenario expects, and write the report. Exit 0 only when everything went as expected and
    no requirement was flagged violated during the run (docs/spec.md, the live monitor), 130
    when interrupted. Scenarios are the kitchen's: another system (--spec) is refused."""
    from services.scenario.model import ScenarioError, library, load_scenario

    security_switches(acl, tls)
    if list_:
        for stem, sc in library().items():
            typer.echo(f"{stem:24s} {sc.name}: {sc.description}")
        return
    if name is None:
        raise fail("name a scenario file or a library scenario (roco scenario --list)", code=2)
    path = kitchen_spec(spec, "roco scenario", "plays the kitchen's scenarios, whose steps name its agents")
    try:
        sc = load_scenario(name)
    except ScenarioError as exc:
        raise fail(str(exc), code=2) from None
    face = ros2_args(ros2, ros2_domain, ros2_namespace)
    watch = live_watch(f"roco scenario {sc.name}", live, quiet, load(path))
    run_scenario(
        sc,
        runs_dir,
        spec=path,
        realtime=realtime,
        quiet=quiet,
        record=record,
        view=view,
        watch=watch,
        gateway=gateway,
        ros2=face,
    )
