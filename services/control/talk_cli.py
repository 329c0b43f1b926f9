"""``roco send`` and ``roco disturb``: give a running fleet a command, or move an object of
its simulated kitchen."""

from __future__ import annotations

import queue
import time
import uuid
from pathlib import Path
from typing import Annotated

import msgspec
import typer

from services.cli_common import (
    CredentialsOption,
    FleetRunsDir,
    RouterOption,
    SpecFile,
    endpoint_of,
    fail,
    fleet_system,
    operator_session,
)
from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport
from services.runtime.reports import MissedOutcomes, ReportFilter, follow_reports, next_report
from services.runtime.session import alive_agents

talk_app = typer.Typer()


def _show_notice(report: HumanReport) -> None:
    """What an agent told the person (a_hi's ``notice`` report), one line naming who said it."""
    typer.echo(report.notice_line)


@talk_app.command(short_help="Give a running fleet a command and wait for its outcome.")
def send(
    command: Annotated[str, typer.Argument(help="what the person says")],
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    timeout: Annotated[float, typer.Option(help="seconds to wait for the outcome")] = 900.0,
    priority: Annotated[int, typer.Option(help="larger is more urgent")] = 0,
    person: Annotated[
        str, typer.Option(help="who speaks: a_hi keeps a conversation per person ('it', questions back)")
    ] = "",
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """Give a running fleet a command and wait for the final report of the agent that plays
    the person's role in its specification (--spec, else the fleet's: a_hi in the kitchen);
    what agents tell the person meanwhile (notices) is shown with who said it. Reports given
    while this session was cut off from it (the router restarted) come when it is back, each
    shown once; after 10 s without one, the agent is asked for the outcome, which a_hi keeps
    across its restarts (services/runtime/reports.py)."""
    system = fleet_system(spec, runs_dir, router)
    interface = system.playing("person")
    if interface is None:
        raise fail(f'no agent of {system.system} plays the person\'s role (role = "person")', code=2)
    endpoint = endpoint_of(router, runs_dir)
    session = operator_session(endpoint, credentials, None if router else runs_dir)
    reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
    follow_reports(session, reports.put)  # also what a_hi said while the router was away
    shown = ReportFilter()
    if interface not in alive_agents(session):
        session.close()
        raise fail(f"{interface} is not alive at {endpoint}")
    request_id = uuid.uuid4().hex[:8]
    said = HumanInput(text=command, request_id=request_id, priority=priority, person=person)
    session.put(keys.HUMAN_IN, msgspec.json.encode(said))
    deadline = time.monotonic() + timeout
    missed = MissedOutcomes(session)
    try:
        while (report := next_report(reports, request_id, shown, missed, deadline, _show_notice)) is not None:
            typer.echo(f"{report.kind.value}: {report.text}")
            if report.kind in FINAL_REPORTS:
                if not report.done_as_asked:
                    raise typer.Exit(1)
                return
        raise fail(f"no outcome within {timeout:.0f} s")
    finally:
        session.close()


@talk_app.command(short_help="Move or tip over an object of the simulated kitchen.")
def disturb(
    obj: Annotated[str, typer.Argument(metavar="OBJECT", help="a free body of the kitchen: jar, bowl, cup")],
    dx: Annotated[float, typer.Option(help="metres along world x")] = 0.0,
    dy: Annotated[float, typer.Option(help="metres along world y")] = 0.0,
    dz: Annotated[float, typer.Option(help="metres along world z")] = 0.0,
    tilt: Annotated[float, typer.Option(help="radians about world x: tips the object over")] = 0.0,
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    credentials: CredentialsOption = None,
) -> None:
    """Move or knock over an object of the simulated kitchen, as a person would (a disturbance
    of the world, not a robot command): ag_ex moves the body and its content and stops them."""
    import json

    from velma.executor.ground_truth import CONTAINERS

    if obj not in CONTAINERS:
        raise fail(f"cannot move {obj!r}: the kitchen's movable objects are {', '.join(CONTAINERS)}", code=2)
    endpoint = endpoint_of(router, runs_dir)
    session = operator_session(endpoint, credentials, None if router else runs_dir)
    try:
        if "ag_ex" not in alive_agents(session):
            raise fail(f"ag_ex is not alive at {endpoint}")
        session.put(keys.SIM_DISTURB, json.dumps({"object": obj, "delta": [dx, dy, dz], "tilt": tilt}))
    finally:
        session.close()
    turn = f", tilted {tilt:+.2f} rad" if tilt else ""
    typer.echo(f"roco: asked ag_ex to move the {obj} by ({dx:+.3f}, {dy:+.3f}, {dz:+.3f}) m{turn}")
