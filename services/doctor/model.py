"""One check of ``roco doctor``: what it looked for, whether it was found, and how to get it."""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass


class Use(enum.Enum):
    """What a checked item serves; ``RUN`` items are what ``roco run`` cannot do without."""

    RUN = "roco run"
    SPEED = "speed"
    CAMERA = "head camera"
    REALTIME = "roco run --realtime"
    UP = "roco up"
    COMPOSE = "compose fleet"
    VIEWER = "viewer screenshot"
    FLEET = "fleet credentials"
    SETTINGS = "settings"
    EXPORT = "roco export"


@dataclass(frozen=True)
class Check:
    """``name`` (e.g. ``EGL``), ``use``, ``found``, ``detail`` (what was found, or why not) and
    ``how`` (how to get it; empty when found). ``informative``: not an item to get, only a fact
    (e.g. no fleet is up), never counted as missing."""

    name: str
    use: Use
    found: bool
    detail: str
    how: str = ""
    informative: bool = False

    @property
    def missing(self) -> bool:
        return not self.found and not self.informative


def camera_ready(checks: Iterable[Check]) -> bool:
    """Whether an off-screen GL context for the head camera opened (one ``Use.CAMERA`` check
    found: EGL or OSMesa)."""
    return any(c.found for c in checks if c.use is Use.CAMERA)


def run_ready(checks: Iterable[Check], camera: bool = True) -> bool:
    """Whether every item ``roco run`` needs (``Use.RUN``) was found and, when ``camera`` (the
    robot perceives with its head camera: ``ROCO_PERCEPTION`` unset or ``camera``,
    velma/executor/capture.py), a GL context for it (``camera_ready``)."""
    checks = list(checks)
    return not any(c.missing for c in checks if c.use is Use.RUN) and (not camera or camera_ready(checks))
