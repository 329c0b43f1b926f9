"""``roco doctor``: what this machine offers roco, item by item, and how to get what is missing.

Each check (services/doctor/model.py ``Check``) says found or not found, what it found, and
how to get it; each serves one use (``Use``): ``roco run`` itself, the head camera, the 1 kHz
loop in real time, ``roco up``, the compose fleet, the viewer's screenshot, a running fleet's
credentials. ``roco doctor`` exits 0 when everything ``roco run`` needs is there: with the head
camera perceiving (the default, ``ROCO_PERCEPTION`` unset or ``camera``) that includes a GL
context for it.

- services/doctor/environment.py: Python, the libraries pyproject.toml names, the compiled law;
- services/doctor/machine.py: off-screen rendering (EGL, OSMesa), SCHED_FIFO, CPU pinning,
  loopback ports;
- services/doctor/tools.py: the compose fleet's prerequisites (docker, its engine, Compose,
  roco's image, debootstrap, the wheelhouse), Chromium;
- services/doctor/credentials.py: the credentials of the fleet ``roco up`` left under ``runs/``;
- services/doctor/settings.py: the ``ROCO_*`` settings (shared/settings.py), each one's value
  here; one that does not parse is a failed item;
- services/doctor/render.py: the checks, and the settings, as lines or a table.
"""

from __future__ import annotations

from pathlib import Path

from services.doctor.model import Check


def run_checks(runs_dir: Path = Path("runs")) -> list[Check]:
    """Every check, in the order they are shown (a few seconds: MuJoCo's GL is tried in a
    child process, Docker is asked with timeouts)."""
    from services.doctor import credentials, environment, machine, settings, tools

    return [
        *environment.checks(),
        *machine.checks(),
        *tools.checks(),
        *credentials.checks(runs_dir),
        *settings.checks(),
    ]
