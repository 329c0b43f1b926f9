"""Settings for the whole test session.

MuJoCo renders off-screen through EGL: ``MUJOCO_GL`` is read when ``mujoco`` is first
imported, and any test module may be the first to import it (velma/render.py sets the same
default for programs)."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")
