"""``roco disturb``: move or tip over an object of a running fleet's simulated kitchen
(services/control/talk.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import (
    CredentialsOption,
    FleetRunsDir,
    RouterOption,
    endpoint_of,
    fail,
    operator_session,
)
from services.runtime.session import alive_agents

disturb_app = typer.Typer()


@disturb_app.command(short_help="Move or tip over an object of the simulated kitchen.")
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
    from services.control.talk import disturb as ask_disturb
    from velma.executor.ground_truth import CONTAINERS

    if obj not in CONTAINERS:
        raise fail(f"cannot move {obj!r}: the kitchen's movable objects are {', '.join(CONTAINERS)}", code=2)
    endpoint = endpoint_of(router, runs_dir)
    session = operator_session(endpoint, credentials, None if router else runs_dir)
    try:
        if "ag_ex" not in alive_agents(session):
            raise fail(f"ag_ex is not alive at {endpoint}")
        ask_disturb(session, obj, (dx, dy, dz), tilt)
    finally:
        session.close()
    turn = f", tilted {tilt:+.2f} rad" if tilt else ""
    typer.echo(f"roco: asked ag_ex to move the {obj} by ({dx:+.3f}, {dy:+.3f}, {dz:+.3f}) m{turn}")
