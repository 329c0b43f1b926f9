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
the other, so that no two of them compete for the CPUs while the other workers take the rest.
Their fleets run lean (:func:`lean_fleets`): no Rerun recording, no figures in the report,
unless the module is marked ``as_users_run``."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

import velma.gl  # noqa: F401  (chooses MUJOCO_GL before any test imports MuJoCo)
from shared.settings import Settings
from tests.support.machine import missing_gl

if missing_gl() is not None:
    os.environ.setdefault("ROCO_PERCEPTION", "truth")


def pytest_report_header() -> list[str]:
    why = missing_gl()
    if why is None:
        return []
    return [f"{why}: fleets perceive with the ground truth (ROCO_PERCEPTION=truth), camera tests skip"]


FLEET_MODULES = pytest.StashKey[set[str]]()
"""The node ids of the modules with a test marked ``fleet`` (found at collection)."""
LEAN = ("rerun", "report_figures")
"""The settings a fleet test's run goes without unless its module is marked ``as_users_run``:
the Rerun recording (``roco run --record``'s default; ag_ex's head-camera renders with it) and
the report's figures, what a run spends most of its CPU on besides the robot and the agents."""


@pytest.fixture(scope="module", autouse=True)
def lean_fleets(request: pytest.FixtureRequest) -> Iterator[None]:
    """In a module with a test marked ``fleet``, the fleets its tests start record nothing with
    Rerun and draw no figures in their reports (:data:`LEAN` set to 0 in this process's
    environment, which they inherit), unless the module is marked ``as_users_run``: the main
    pour (tests/integration/test_pour_run.py) checks those on the run as users run it;
    tests/viewer and tests/report check them in depth."""
    module = request.node
    if module.nodeid not in request.config.stash.get(FLEET_MODULES, set()) or module.get_closest_marker(
        "as_users_run"
    ):
        yield
        return
    with pytest.MonkeyPatch.context() as patch:
        for name in LEAN:
            patch.setenv(Settings.env_name(name), "0")
        yield


FLEET_GROUP = pytest.mark.xdist_group("fleet")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    # first: pytest-xdist's own hook reads the xdist_group marks on the worker, and runs before a
    # conftest's by default
    modules: set[str] = set()
    for item in items:
        if item.get_closest_marker("fleet") is not None:
            item.add_marker(FLEET_GROUP)
            module = item.getparent(pytest.Module)
            if module is not None:
                modules.add(module.nodeid)
    if items:
        items[0].config.stash[FLEET_MODULES] = modules


def pytest_runtest_setup(item: pytest.Item) -> None:
    """Under ``--dist loadgroup`` (an xdist worker), a fleet test fails at once unless xdist
    grouped it: its node id carries the group. Ungrouped, xdist spreads the fleets over every
    worker, whole fleets compete for the CPUs and each worker builds the module fixtures again.
    pytest 9.2 with pytest-xdist 3.8 drops the group silently (xdist marks it in the node id,
    which pytest 9.2 no longer reads), hence the pin in pyproject.toml."""
    if not getattr(item.config.option, "loadgroup", False) or item.get_closest_marker("fleet") is None:
        return
    if not item.nodeid.endswith("@fleet"):
        pytest.fail(
            f"pytest-xdist did not put this fleet test in its group (pytest {pytest.__version__}"
            " ignores xdist_group with this pytest-xdist): install the versions pyproject.toml"
            " pins, pip install -e '.[dev]'",
            pytrace=False,
        )
