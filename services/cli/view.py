"""``roco view``: a Rerun viewer on a run's recording or on a live fleet (services/viewer/view.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import fail, run_folder
from services.runtime.session import port_in_use

view_app = typer.Typer()


def _web_viewer(web: bool | None, web_port: int | None) -> bool | None:
    """Whether `roco view` opens the web viewer (None: by display): --web-port implies --web,
    and exits 2 with --native."""
    if web_port is None:
        return web
    if web is False:
        raise fail("--web-port is the web viewer's port: not with --native", code=2)
    return True


def _check_recording(run_dir: Path | None) -> None:
    """Exit 1 when ``run_dir`` (a run folder or .rrd) does not exist or is not a run folder."""
    if run_dir is not None and not run_dir.exists():
        raise fail(f"{run_dir}: no such run folder or recording")
    if run_dir is not None and run_dir.is_dir():
        run_folder(run_dir)


@view_app.command(short_help="Open a Rerun viewer on a run's recording or on a live fleet.")
def view(
    run_dir: Annotated[
        Path | None,
        typer.Argument(metavar="[RUN]", help="a run folder or .rrd (none: wait for a live fleet)"),
    ] = None,
    web: Annotated[
        bool | None,
        typer.Option(
            "--web/--native", help="web viewer on localhost or the native one (default: by display)"
        ),
    ] = None,
    web_port: Annotated[
        int | None,
        typer.Option(
            min=1,
            max=65535,
            help="the web viewer's port on 127.0.0.1 (implies --web) [default: a free one]",
            show_default=False,
        ),
    ] = None,
    grpc_port: Annotated[
        int | None,
        typer.Option(
            min=1,
            max=65535,
            help="the port logging SDKs (a live fleet) connect to [default: a free one]",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Open a Rerun viewer on a past run's recording, or an empty one a live fleet streams to:
    the native viewer where a display exists, otherwise the web viewer served on localhost
    (its URL printed). A port asked for that is in use is refused before anything starts."""
    from services.viewer.view import PortInUse, start_viewer

    web = _web_viewer(web, web_port)
    _check_recording(run_dir)
    try:
        viewer = start_viewer(run_dir, web=web, web_port=web_port, grpc_port=grpc_port)
    except PortInUse as exc:
        option = "--web-port" if exc.port == web_port else "--grpc-port"
        raise fail(port_in_use("127.0.0.1", exc.port, option), code=2) from None
    except Exception as exc:
        raise fail(f"cannot start the viewer: {exc}") from None
    where = viewer.web_url or f"native viewer, SDKs connect to {viewer.grpc_url}"
    typer.echo(f"roco: Rerun viewer {where} (pid {viewer.pid}; stop it with: kill -- -{viewer.pid})")
