"""``roco send``: give a running fleet a command and wait for its outcome
(services/control/talk.py, services/runtime/reports.py)."""

from __future__ import annotations

import queue
import time
from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import (
    CredentialsOption,
    FleetRunsDir,
    RouterOption,
    SpecFile,
    endpoint_of,
    fail,
    fleet_system,
    operator_session,
)
from services.control.talk import say
from services.runtime.human import FINAL_REPORTS, HumanReport
from services.runtime.reports import MissedOutcomes, ReportFilter, follow_reports, next_report
from services.runtime.session import alive_agents

send_app = typer.Typer()


def _show_notice(report: HumanReport) -> None:
    """What an agent told the person (a_hi's ``notice`` report), one line naming who said it."""
    typer.echo(report.notice_line)


@send_app.command(short_help="Give a running fleet a command and wait for its outcome.")
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
    request_id = say(session, command, priority, person)
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
