"""What this machine lacks, for the tests that need a system tool or service: one pytest marker
each, skipping with a reason that names what to install — the same probes and words as
``roco doctor`` (services/doctor/).

- :data:`needs_two_hosts`: root, iproute2's ``ip`` and nftables' ``nft`` (``roco hosts``).
- :data:`needs_gl`: MuJoCo rendering off-screen (EGL, else OSMesa): the head camera itself.
- :data:`needs_camera`: the same, for a test of a whole fleet that checks what the head camera
  perceived (an Observation's pose or content count, the camera in the recording).
- :data:`needs_chromium`: Debian's Chromium (the web viewer rendered headless).

Without off-screen rendering a fleet perceives with the physics' ground truth
(tests/conftest.py sets ``ROCO_PERCEPTION=truth``, as ``roco run`` does by itself,
velma/executor/capture.py ``perception_mode``). A test that would then measure the truth in the
camera's place does not run on it: it skips, marked :data:`needs_camera`, with a reason that
says so. Fleet tests that judge by the world the run left (the physics' final scene) run either
way.

`.ci/run` installs everything these markers probe for, and fails, before pytest, with one line
when MuJoCo does not render (services/doctor/machine.py ``cannot_render``), so in CI none of
them skips. What CI cannot run, and why:

- tests/bench/test_jade.py, the two tests marked ``needs_jade`` (a real JADE platform against
  roco's round trip): they need a JADE source tree in ``ROCO_JADE_HOME``, and no package
  registry ships JADE's source (CI installs the JDK only);
- tests/cli/test_bad_paths.py ``test_a_folder_without_write_permission_is_refused``: CI runs as
  root, and root writes into a folder without write permission.

(The plain-TCP variants of tests/security/test_access_control.py's two TLS-only tests skip
everywhere: the fixture's parameter, not the machine.)

Each probe runs once per test session (the rendering probe starts a child interpreter, ≈ 0.5 s).
"""

from __future__ import annotations

import functools

import pytest

from services.doctor.machine import cannot_render
from services.doctor.tools import chromium_check
from services.hosts.netns import unavailable


@functools.cache
def missing_gl() -> str | None:
    """Why MuJoCo cannot render off-screen here, with EGL nor OSMesa (with the packages to
    install), or None when one renders a non-constant image."""
    return cannot_render()


@functools.cache
def missing_chromium() -> str | None:
    """Why there is no Chromium here (with the package), or None."""
    check = chromium_check()
    return None if check.found else f"Chromium is not installed ({check.how})"


TRUTH_INSTEAD = (
    "the fleet would perceive with the physics' ground truth (ROCO_PERCEPTION=truth), "
    "not with the head camera this test checks"
)
"""Why a :data:`needs_camera` test skips, after what is missing."""

needs_two_hosts = pytest.mark.skipif(
    unavailable() is not None, reason=f"two hosts on this machine: {unavailable()}"
)
needs_gl = pytest.mark.skipif(missing_gl() is not None, reason=str(missing_gl()))
needs_camera = pytest.mark.skipif(missing_gl() is not None, reason=f"{missing_gl()}: {TRUTH_INSTEAD}")
needs_chromium = pytest.mark.skipif(missing_chromium() is not None, reason=str(missing_chromium()))
