"""Programs roco can use: a Docker engine, Compose and roco's image (the compose fleet,
deploy/compose.yaml) and Chromium (scripts/viewer_screenshot.py)."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable, Sequence

from services.doctor.model import Check, Use

TIMEOUT_S = 15.0
IMAGE = "roco:latest"  # deploy/compose.yaml's default ROCO_IMAGE
CHROMIUM_NAMES = ("chromium", "chromium-browser")  # scripts/viewer_screenshot.py CHROMIUM_NAMES
DOCKER_HOW = "apt-get install docker.io (Debian), then start it (systemctl start docker or dockerd &)"

Runner = Callable[[Sequence[str]], tuple[int, str]]


def run(args: Sequence[str]) -> tuple[int, str]:
    """(exit status, stdout or else stderr, stripped) of ``args``; 127 when the program is
    missing, 124 past ``TIMEOUT_S``."""
    try:
        done = subprocess.run(list(args), capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    except FileNotFoundError:
        return 127, f"{args[0]}: not found"
    except subprocess.TimeoutExpired:
        return 124, f"no answer within {TIMEOUT_S:.0f} s"
    text = (done.stdout.strip() or done.stderr.strip()).splitlines()
    return done.returncode, (text[-1] if text else "")


def docker_checks(runner: Runner = run, which: Callable[[str], str | None] = shutil.which) -> list[Check]:
    """The engine (``docker version``'s server), Compose (``docker compose`` or
    ``docker-compose``) and roco's image."""
    if which("docker") is None:
        return [Check("Docker engine", Use.COMPOSE, False, "no docker on PATH", DOCKER_HOW)]
    code, out = runner(["docker", "version", "--format", "{{.Server.Version}}"])
    engine = code == 0 and bool(out)
    found = [
        Check(
            "Docker engine",
            Use.COMPOSE,
            engine,
            f"server {out}" if engine else f"the client cannot reach an engine: {out}",
            "" if engine else DOCKER_HOW,
        )
    ]
    found.append(_compose_check(runner, which))
    if engine:
        code, out = runner(["docker", "image", "inspect", "--format", "{{.Id}}", IMAGE])
        found.append(
            Check(
                f"image {IMAGE}",
                Use.COMPOSE,
                code == 0,
                "built" if code == 0 else "not built",
                "" if code == 0 else "scripts/build_image.sh (docs/deploy.md)",
            )
        )
    return found


def _compose_check(runner: Runner, which: Callable[[str], str | None]) -> Check:
    """Compose: ``docker compose``, else ``docker-compose``."""
    code, out = runner(["docker", "compose", "version", "--short"])
    if code == 0:
        return Check("Compose", Use.COMPOSE, True, f"docker compose {out}")
    if (
        which("docker-compose") is not None
        and (r := runner(["docker-compose", "version", "--short"]))[0] == 0
    ):
        return Check("Compose", Use.COMPOSE, True, f"docker-compose {r[1]}")
    return Check(
        "Compose",
        Use.COMPOSE,
        False,
        "neither 'docker compose' nor 'docker-compose'",
        "apt-get install docker-compose (or the compose plugin)",
    )


def chromium_check(which: Callable[[str], str | None] = shutil.which) -> Check:
    """Chromium on PATH, for the viewer's screenshot (scripts/viewer_screenshot.py)."""
    path = next((p for p in map(which, CHROMIUM_NAMES) if p), None)
    return Check(
        "Chromium",
        Use.VIEWER,
        path is not None,
        path or f"none of {', '.join(CHROMIUM_NAMES)} on PATH",
        "" if path else "apt-get install chromium",
    )


def checks() -> list[Check]:
    return [*docker_checks(), chromium_check()]
