"""``roco doctor``: what this machine offers roco, and how to get what is missing
(services/doctor/)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from shared.settings import Settings

doctor_app = typer.Typer()


@doctor_app.command(short_help="Check what this machine offers roco, and how to get what is missing.")
def doctor(
    runs_dir: Annotated[Path, typer.Option(help="where 'roco up' keeps its fleet state")] = Path("runs"),
    compose: Annotated[
        bool, typer.Option("--compose", help="only what the compose fleet needs (docs/deploy.md)")
    ] = False,
) -> None:
    """Check, item by item, what roco can use on this machine: Python and the libraries,
    the compiled control law, a free loopback port, EGL or OSMesa for the head camera,
    SCHED_FIFO and CPU pinning for `--realtime`, the compose fleet's prerequisites (below),
    Chromium for the viewer's screenshot, and the credentials of the
    fleet `roco up` left under `runs/`. Then every `ROCO_*` setting (docs/settings.md): its
    value here, its default and what it sets; a value that does not parse is a failed item.

    Each item says found or not found and how to get it. Exit 0 when everything `roco run`
    needs is there (with the head camera perceiving, the default where libEGL or libOSMesa is
    installed, an off-screen GL context that opens), 1 otherwise. Takes a few seconds: MuJoCo's
    GL is tried in a child process, Docker is asked with time limits.

    With --compose, only the compose fleet's prerequisites (docs/deploy.md): the docker client
    (Debian's docker.io), an engine that answers it, Compose (`docker compose` or Debian's
    `docker-compose`), roco's image and, until it is built, debootstrap and the wheelhouse of
    scripts/build_image.sh; each one missing is named with how to get it, and the exit is 1."""
    from rich.console import Console

    from services.doctor import run_checks
    from services.doctor.model import run_ready
    from services.doctor.render import compose_verdict, show, verdict
    from services.doctor.settings import readings
    from velma.executor.capture import perception_mode

    if compose:
        from services.doctor.tools import docker_checks

        found = docker_checks()
        show(found, Console(highlight=False))
        typer.echo(compose_verdict(found))
        if any(c.missing for c in found):
            raise typer.Exit(1)
        return
    checks = run_checks(runs_dir)
    try:
        camera = perception_mode() == "camera"
    except ValueError:  # a bad ROCO_PERCEPTION: roco run refuses it; judge as the default
        camera = True
    fallback = not camera and Settings.from_env(only=("perception",)).perception is None
    show(checks, Console(highlight=False), readings())
    typer.echo(verdict(checks, camera, truth_by_default=fallback))
    if not run_ready(checks, camera):
        raise typer.Exit(1)
