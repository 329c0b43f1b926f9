"""Programs roco can use: what the compose fleet needs on a machine with Debian's packages and
no registry (the Docker client and engine, Compose v2 or Debian's ``docker-compose`` 1.29,
``debootstrap`` for scripts/build_image.sh's base image and its wheelhouse, roco's image;
docs/deploy.md) and Chromium (scripts/viewer_screenshot.py)."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from services.doctor.model import Check, Use
from shared.settings import deployment_name

TIMEOUT_S = 15.0
IMAGES = ("roco:latest", "roco-viewer:latest", "roco-robot:latest")
"""deploy/compose.yaml's default ROCO_IMAGE, ROCO_VIEWER_IMAGE and ROCO_ROBOT_IMAGE (the runtime,
viewer and robot targets of deploy/Dockerfile, which scripts/build_image.sh builds together)."""
CHROMIUM_NAMES = ("chromium", "chromium-browser")  # scripts/viewer_screenshot.py CHROMIUM_NAMES
DOCKER_HOW = "apt-get install docker.io (Debian)"
ENGINE_HOW = "start it: systemctl start docker; without systemd: service docker start, or dockerd &"
COMPOSE_HOW = "apt-get install docker-compose (Debian's 1.29), or Compose v2 (docker compose)"
DEBOOTSTRAP_HOW = "apt-get install debootstrap"
IMAGE_HOW = "scripts/build_image.sh, as root (docs/deploy.md): builds them without a registry"
WHEELHOUSE_HOW = "scripts/build_image.sh makes it; this host needs PyPI for that, once"
SERVICES_UID = 10001  # deploy/Dockerfile's user roco, deploy/compose.yaml's default ROCO_UID
HOST_FOLDERS = ((deployment_name("runs"), "../runs"), (deployment_name("certs"), "./certs"))
"""The host folders the compose services write (variable, deploy/compose.yaml's default,
relative to deploy/)."""

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


def images_check(runner: Runner = run) -> Check:
    """Whether roco's images (:data:`IMAGES`) are built here (``docker image inspect``); the
    detail names those that are not."""
    missing = [i for i in IMAGES if runner(["docker", "image", "inspect", "--format", "{{.Id}}", i])[0] != 0]
    built = not missing
    return Check(
        "images",
        Use.COMPOSE,
        built,
        f"{', '.join(IMAGES)} built" if built else f"not built: {', '.join(missing)}",
        "" if built else IMAGE_HOW,
    )


def docker_checks(
    runner: Runner = run,
    which: Callable[[str], str | None] = shutil.which,
    root: Path | None = None,
    env: Mapping[str, str] | None = None,
) -> list[Check]:
    """Every prerequisite of the compose fleet, each its own check: the ``docker`` client, an
    engine that answers it (``docker version``'s server), Compose (``docker compose``, else
    ``docker-compose``), roco's images and, while they are not built, ``debootstrap`` (what
    scripts/build_image.sh makes the base image with when no registry gives one), the
    wheelhouse (:func:`wheelhouse_check`, of the project at ``root``, default this one) and the
    host folders the services write (:func:`host_folders_check`, ``env`` default os.environ)."""
    client = which("docker")
    found = [
        Check(
            "docker",
            Use.COMPOSE,
            client is not None,
            client or "no docker on PATH",
            "" if client else DOCKER_HOW,
        )
    ]
    engine = False
    if client is not None:
        code, out = runner(["docker", "version", "--format", "{{.Server.Version}}"])
        engine = code == 0 and bool(out)
        found.append(
            Check(
                "Docker engine",
                Use.COMPOSE,
                engine,
                f"server {out}" if engine else f"the client cannot reach an engine: {out}",
                "" if engine else ENGINE_HOW,
            )
        )
    found.append(_compose_check(runner, which, client is not None))
    built = False
    if engine:
        found.append(images_check(runner))
        built = found[-1].found
    found.append(_debootstrap_check(which, built))
    found.append(wheelhouse_check(built, root))
    found.append(host_folders_check(root, env))
    return found


def host_folders_check(root: Path | None, env: Mapping[str, str] | None = None) -> Check:
    """Whether the host folders the compose services write (:data:`HOST_FOLDERS`, as ``env``
    (default os.environ) names them, relative to ``root``'s deploy/) exist and are writable by
    the services' user (``ROCO_UID``, default :data:`SERVICES_UID`): its own, or writable by
    all. Docker makes a missing one root's, and the services then cannot write it."""
    env = os.environ if env is None else env
    uid, gid = _services_user(env)
    folders = _host_folders(root, env)
    wrong = [problem for folder in folders if (problem := _unwritable(folder, uid))]
    if not wrong:
        return Check("host folders", Use.COMPOSE, True, f"the run and credentials folders are uid {uid}'s")
    both = " ".join(map(str, folders))
    return Check(
        "host folders",
        Use.COMPOSE,
        False,
        f"the services (uid {uid}) cannot write: {'; '.join(wrong)}",
        f"mkdir -p {both} && chown {uid}:{gid} {both} (or ROCO_UID: docs/deploy.md)",
    )


def _services_user(env: Mapping[str, str]) -> tuple[int, int]:
    """The compose services' uid and gid (``ROCO_UID``, ``ROCO_GID``; :data:`SERVICES_UID`)."""
    ids = [env.get(deployment_name(key)) or str(SERVICES_UID) for key in ("uid", "gid")]
    uid, gid = (int(i) if i.isdigit() else SERVICES_UID for i in ids)
    return uid, gid


def _host_folders(root: Path | None, env: Mapping[str, str]) -> list[Path]:
    """:data:`HOST_FOLDERS` as ``env`` names them, relative to the deploy/ folder of ``root``
    (default this project)."""
    if root is None:
        from services.deploy.compose import PROJECT

        root = PROJECT
    return [(root / "deploy" / (env.get(v) or d)).resolve() for v, d in HOST_FOLDERS]


def _unwritable(folder: Path, uid: int) -> str | None:
    """Why ``uid`` cannot write ``folder`` (missing, another's), or None (its own and writable
    by its owner, writable by all, or ``uid`` is root)."""
    try:
        info = folder.stat()
    except OSError:
        return f"{folder} missing"
    if uid == 0 or (info.st_uid == uid and info.st_mode & 0o200) or info.st_mode & 0o002:
        return None
    return f"{folder} is uid {info.st_uid}'s"


WHEELHOUSE = Path("deploy", "wheelhouse")
"""scripts/build_image.sh's wheelhouse, in the project; its ``.pyproject.sha256`` names the
pyproject.toml it was made for."""


def wheelhouse_check(built: bool, root: Path | None = None) -> Check:
    """Whether scripts/build_image.sh's wheelhouse under ``root`` (default: this project) matches
    its pyproject.toml (else the host needs PyPI once to make it); only a fact once roco's
    image is built."""
    if root is None:
        from services.deploy.compose import PROJECT

        root = PROJECT
    stamp = root / WHEELHOUSE / ".pyproject.sha256"
    try:
        want = hashlib.sha256((root / "pyproject.toml").read_bytes()).hexdigest()
        ok = stamp.read_text().strip() == want
    except OSError:
        ok = False
    if ok:
        return Check("wheelhouse", Use.COMPOSE, True, f"{WHEELHOUSE} matches pyproject.toml")
    detail = f"{WHEELHOUSE} not made for this pyproject.toml"
    if built:
        return Check(
            "wheelhouse", Use.COMPOSE, False, f"{detail}; not needed: the images are built", informative=True
        )
    return Check("wheelhouse", Use.COMPOSE, False, detail, WHEELHOUSE_HOW)


def _debootstrap_check(which: Callable[[str], str | None], built: bool) -> Check:
    """debootstrap on PATH; only a fact once roco's image is built (nothing left to make)."""
    path = which("debootstrap")
    if path is None and built:
        return Check(
            "debootstrap",
            Use.COMPOSE,
            False,
            "not on PATH; not needed: the images are built",
            informative=True,
        )
    return Check(
        "debootstrap",
        Use.COMPOSE,
        path is not None,
        path or "not on PATH (scripts/build_image.sh makes the base image with it without a registry)",
        "" if path else DEBOOTSTRAP_HOW,
    )


def _compose_check(runner: Runner, which: Callable[[str], str | None], docker: bool = True) -> Check:
    """Compose: ``docker compose`` (asked only where ``docker`` is on PATH), else
    ``docker-compose``."""
    if docker and (r := runner(["docker", "compose", "version", "--short"]))[0] == 0:
        return Check("Compose", Use.COMPOSE, True, f"docker compose {r[1]}")
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
        COMPOSE_HOW,
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
