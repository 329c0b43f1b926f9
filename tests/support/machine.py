"""What this machine lacks, for the tests that need a system tool or service: one pytest marker
each, skipping with a reason that names what to install — the same probes and words as
``roco doctor`` (services/doctor/). `.ci/run` installs all of them, so CI runs every test.

- :data:`needs_two_hosts`: root, iproute2's ``ip`` and nftables' ``nft`` (``roco hosts``).
- :data:`needs_gl`: an off-screen GL context for MuJoCo (EGL, else OSMesa): the head camera.
- :data:`needs_chromium`: Debian's Chromium (the web viewer rendered headless).

Each probe runs once per test session (a GL probe starts a child interpreter, ≈ 0.3 s).
"""

from __future__ import annotations

import functools

import pytest

from services.doctor.machine import rendering_checks
from services.doctor.tools import chromium_check
from services.hosts.netns import unavailable


@functools.cache
def missing_gl() -> str | None:
    """Why MuJoCo cannot open an off-screen GL context here (with the packages to install), or
    None when EGL or OSMesa works."""
    checks = rendering_checks()
    if any(c.found for c in checks):
        return None
    return f"no off-screen GL context (EGL or OSMesa) for MuJoCo: {checks[0].how}"


@functools.cache
def missing_chromium() -> str | None:
    """Why there is no Chromium here (with the package), or None."""
    check = chromium_check()
    return None if check.found else f"Chromium is not installed ({check.how})"


needs_two_hosts = pytest.mark.skipif(
    unavailable() is not None, reason=f"two hosts on this machine: {unavailable()}"
)
needs_gl = pytest.mark.skipif(missing_gl() is not None, reason=str(missing_gl()))
needs_chromium = pytest.mark.skipif(missing_chromium() is not None, reason=str(missing_chromium()))
