"""``roco gateway``: the ACL gateway in the foreground (services/gateway/serve.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import FleetRunsDir, RouterOption, SpecFile, endpoint_of, fleet_spec
from shared.settings import GATEWAY_PORT

gateway_app = typer.Typer()


@gateway_app.command(short_help="Bridge the fleet to other FIPA platforms (HTTP, SC00084).")
def gateway(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    host: Annotated[str, typer.Option(help="interface the HTTP transport listens on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=1, max=65535, help="port of the HTTP transport")] = GATEWAY_PORT,
    address: Annotated[
        str | None,
        typer.Option(help="the URL other platforms post to (default http://HOST:PORT/acc)"),
    ] = None,
    spec: SpecFile = None,
    platform: Annotated[
        list[str] | None,
        typer.Option(
            help="PLATFORM=URL[,URL…]: answer every agent …@PLATFORM only at these addresses "
            "(repeatable; default: a name is bound to the peer that first used it)"
        ),
    ] = None,
) -> None:
    """Serve the FIPA HTTP message transport (FIPA SC00084, SC00085 XML envelope, SC00070
    string form) for agents of other FIPA platforms (JADE…): what they send to a roco agent
    the specification lets them address (its external role, x_fipa: a_hi on C8) is put on
    the fleet's Zenoh under their own names, and the answers are posted back to them; anything
    else is refused (FIPA refuse or not-understood) and counted. The specification is --spec,
    else that of the fleet of 'roco up' (unless --router), else the shipped one. Runs until
    Ctrl-C (docs/gateway.md)."""
    from services.gateway.serve import GatewayConfig
    from services.gateway.serve import main as run_gateway

    spec_file = fleet_spec(spec, runs_dir, router)
    config = GatewayConfig(
        endpoint_of(router, runs_dir), host, port, address, spec_file, tuple(platform or ())
    )
    code = run_gateway(config)
    if code:
        raise typer.Exit(code)
