"""The OpenGL platform MuJoCo renders off-screen with (the head camera, velma/render.py),
chosen once, before MuJoCo is first imported: importing any ``velma`` module chooses it.

MuJoCo reads ``MUJOCO_GL`` when ``mujoco`` is first imported. A value already set is kept.
Otherwise: ``egl`` when libEGL is installed (software EGL, Mesa's llvmpipe, is enough),
``osmesa`` when libOSMesa is, else ``disable``: MuJoCo then simulates without a GL platform
and rendering raises. ``MUJOCO_GL=egl`` without libEGL would break ``import mujoco``
altogether (PyOpenGL raises ``AttributeError`` at import, which MuJoCo does not catch), so
the platform is only named when its library is there. Children inherit the choice through
the environment."""

from __future__ import annotations

import ctypes.util
import os
import sys
from collections.abc import MutableMapping

PLATFORMS = (("egl", "EGL"), ("osmesa", "OSMesa"))
"""Off-screen platforms in order of preference, each with its shared library's name."""
NONE = "disable"
"""``MUJOCO_GL`` when no off-screen library is installed."""
HOW = "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0"
"""What gives a Debian or Ubuntu machine software EGL (``roco doctor`` says the same)."""


def choose(environ: MutableMapping[str, str] = os.environ) -> str:
    """Set ``environ["MUJOCO_GL"]`` unless set (see the module) and return it."""
    if environ.get("MUJOCO_GL"):
        return environ["MUJOCO_GL"]
    chosen = next((name for name, library in PLATFORMS if ctypes.util.find_library(library)), NONE)
    environ["MUJOCO_GL"] = chosen
    return chosen


def never_renders(environ: MutableMapping[str, str] = os.environ) -> bool:
    """Say that this process never renders: ``environ["MUJOCO_GL"]`` becomes ``disable`` so that
    MuJoCo, first imported after this, loads no GL platform (no PyOpenGL, libEGL or Mesa's
    loader: ≈ 4.6 MiB VmRSS, ≈ 60 modules less; ``import mujoco`` in a fresh interpreter with
    ``egl`` against ``disable``, Python 3.11, mujoco's wheel), and processes it starts
    afterwards inherit that. For the world process and ag_ex's loop (the head camera renders in
    a process of its own). Returns False, changing nothing, when MuJoCo is imported already: its
    platform is chosen."""
    if "mujoco" in sys.modules:
        return False
    environ["MUJOCO_GL"] = NONE
    return True


def renders(environ: MutableMapping[str, str] = os.environ) -> bool:
    """Whether MuJoCo has a GL platform here (after :func:`choose`): not ``disable``/``off``/…"""
    return environ.get("MUJOCO_GL", "").strip().lower() not in ("", NONE, "disabled", "off", "false", "0")


choose()
