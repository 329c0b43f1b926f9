"""Settings for the whole test session.

MuJoCo reads ``MUJOCO_GL`` when ``mujoco`` is first imported, and any test module may be the
first to import it: velma/gl.py chooses the off-screen platform here, before any test module.

On a machine where MuJoCo does not render off-screen (no EGL, no OSMesa), the fleets the tests
start perceive with the physics' ground truth (``ROCO_PERCEPTION=truth``) instead of the head
camera, and the tests of the camera, and those of a fleet that check what the camera perceived,
skip with the packages to install (tests/support/machine.py ``needs_gl``, ``needs_camera``); the
session's header says so.

The suite runs on every CPU (pytest-xdist, pyproject.toml): tests marked ``fleet`` (a whole
fleet with ag_ex simulating a task, about a core and a half each) go to one worker, one after
the other, so that no two of them compete for the CPUs while the other workers take the rest."""

from __future__ import annotations

import os

import pytest

import velma.gl  # noqa: F401  (chooses MUJOCO_GL before any test imports MuJoCo)
from tests.support.machine import missing_gl

if missing_gl() is not None:
    os.environ.setdefault("ROCO_PERCEPTION", "truth")


def pytest_report_header() -> list[str]:
    why = missing_gl()
    if why is None:
        return []
    return [f"{why}: fleets perceive with the ground truth (ROCO_PERCEPTION=truth), camera tests skip"]


FLEET_GROUP = pytest.mark.xdist_group("fleet")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("fleet") is not None:
            item.add_marker(FLEET_GROUP)
