"""``roco status``: which agents of a running fleet are alive, their counters, what the
routers refused (services/control/status.py names them) and the requirements the live monitor
flagged violated."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import (
    CredentialsOption,
    FleetRunsDir,
    RouterOption,
    SpecFile,
    endpoint_of,
    fleet_state,
    fleet_system,
    operator_session,
)
from services.runtime.session import alive_agents

if TYPE_CHECKING:
    from services.recorder.flags import FlagsReply
    from services.runtime.counters import CountersReport

status_app = typer.Typer()


def _flag_lines(reply: FlagsReply | None) -> list[str]:
    """`roco status`'s lines of the requirements the live monitor flagged violated, from the
    traffic recorder's ``reply`` (services/recorder/flags.py ``ask_flags``): one per flag,
    ``violated  R3.3 “…”: <event> at <time> (<what it came before>)``, then how many more the
    recorder holds when it sent only the first; one line saying the recorder did not answer
    when ``reply`` is None; none without a flag."""
    if reply is None:
        return [f"{'flags':9s} (the recorder did not answer: live requirement flags unknown)"]
    lines = [f"{'violated':9s} {f.line()}" for f in reply.flags]
    if reply.total > len(reply.flags):
        lines.append(
            f"{'violated':9s} (and {reply.total - len(reply.flags)} more in the run folder's flags.jsonl)"
        )
    return lines


def _counters_text(name: str, alive: set[str], reports: dict[str, CountersReport]) -> str:
    """The tail of `roco status`'s line of ``name``: its counters (the gateway's: what came
    in, was refused, went out; the ROS 2 face's likewise), or that an alive agent did not send
    them in time."""
    from services.runtime.counters import summary

    if name == "gateway" and name in reports:
        from services.gateway.bridge import summary as gateway_summary

        return f"  {gateway_summary(reports[name].counters)}"
    if name == "ros2" and name in reports:
        from services.ros2.face import summary as ros2_summary

        return f"  {ros2_summary(reports[name].counters)}"
    if name in reports:
        return f"  {summary(reports[name].counters)}"
    if name in alive and name != "recorder":  # (the gateway answers as agents do)
        return "  (no counters within the timeout: busy)"
    return ""


@status_app.command(short_help="Which agents are alive, with their counters of input.")
def status(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    counters_timeout: Annotated[
        float, typer.Option(min=0.0, help="seconds to wait for the agents' counters")
    ] = 2.0,
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """List the agents of the specification (--spec, else the fleet's) that hold a liveliness
    token, each alive agent with its counters of received and rejected input (by reason;
    docs/security.md) and the handler and behaviour errors it counted (when any), and what each
    router with access control refused, named (identity, message, key, when); each router is
    named by its host (brain, robot: `roco hosts`) or its endpoint; then one line per
    requirement property the live monitor found violated, as the traffic recorder answers over
    Zenoh (requirement, property, the communicate that violated it, when; docs/spec.md), or one
    line saying the recorder did not answer. Exit 1 if any agent is missing."""
    from services.recorder.flags import ask_flags
    from services.runtime.counters import ask_counters
    from services.runtime.refusals import RefusalReport, collect_reports
    from services.runtime.refusals import summary as refusal_summary

    agents = fleet_system(spec, runs_dir, router).launch_order
    endpoint = endpoint_of(router, runs_dir)
    session = operator_session(endpoint, credentials, None if router else runs_dir)
    refusals: list[RefusalReport] = []
    try:
        alive = alive_agents(session)
        with collect_reports(session, refusals):
            reports = ask_counters(session, alive & {*agents, "gateway", "ros2"}, timeout=counters_timeout)
        flags = ask_flags(session, timeout=counters_timeout)
        mine = {str(z) for z in session.info.routers_zid()}  # the router this session reached
    finally:
        session.close()
    names = _routers_named(runs_dir, endpoint, mine)
    extra = [n for n in ("gateway", "ros2") if n in alive]
    for name in (*agents, "recorder", *extra):
        typer.echo(
            f"{name:9s} {'alive' if name in alive else 'absent'}{_counters_text(name, alive, reports)}"
        )
    for r in sorted(refusals, key=lambda r: names.get(r.router, r.router)):
        name = names.get(r.router, f"{r.router[:8]} (Zenoh id)")
        typer.echo(f"{'router':9s} {name}  {refusal_summary(r)}")
    for line in _flag_lines(flags):
        typer.echo(line)
    if not set(agents) <= alive:
        raise typer.Exit(1)


def _routers_named(runs_dir: Path, endpoint: str, mine: set[str]) -> dict[str, str]:
    """Zenoh id → a name of every router of the fleet in ``runs_dir`` and of the routers
    ``mine`` this session reached (services/control/status.py ``routers_named``)."""
    from services.control.status import routers_named

    state = fleet_state(runs_dir)
    return routers_named(Path(state.run_dir) if state is not None else None, endpoint, mine)
