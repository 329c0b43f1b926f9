"""``roco sniff``: live communicates as they cross Zenoh, in FIPA SC00070 string form
(services/sniff/sniffer.py)."""

from __future__ import annotations

import threading
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
    stop_on_signals,
)

sniff_app = typer.Typer()


@sniff_app.command(short_help="Print live communicates as they cross Zenoh (FIPA SC00070).")
def sniff(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    agent: Annotated[list[str] | None, typer.Option(help="only communicates from or to this agent")] = None,
    channel: Annotated[list[str] | None, typer.Option(help="only this channel of the specification")] = None,
    performative: Annotated[list[str] | None, typer.Option(help="only this performative")] = None,
    conversation: Annotated[str | None, typer.Option(help="only this conversation-id")] = None,
    raw: Annotated[bool, typer.Option(help="print :content exactly as on the wire (SC00070)")] = False,
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """Print live communicates as they cross Zenoh, in FIPA SC00070 string form (like JADE's
    Sniffer), until interrupted. Content is shown as its decoded term unless --raw. Agents,
    channels and content languages are those of --spec, else of the fleet's specification."""
    from services.sniff.sniffer import parse_filters
    from services.sniff.sniffer import sniff as run_sniff

    system = fleet_system(spec, runs_dir, router)  # its content languages registered
    try:
        f = parse_filters(
            agents=agent, channels=channel, performatives=performative, conversation=conversation, spec=system
        )
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    endpoint = endpoint_of(router, runs_dir)
    stop = threading.Event()
    stop_on_signals()
    session = operator_session(endpoint, credentials, None if router else runs_dir)
    try:
        count = run_sniff(
            session,
            agents=f.agents,
            channels=f.channels,
            performatives=f.performatives,
            conversation=f.conversation,
            out=typer.echo,
            stop=stop,
            content=not raw,
        )
    except KeyboardInterrupt:
        stop.set()
        return
    finally:
        session.close()
    typer.echo(f"roco: {count} communicates")
