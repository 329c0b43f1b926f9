"""MuJoCo's off-screen GL platform (velma/gl.py) and what the robot perceives with where there is
none: the ground truth, said once by roco run; a head camera asked for there is refused."""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys

import pytest

from velma.executor.capture import DEFAULT_PERCEPTION, camera_unavailable, perception_mode
from velma.gl import HOW, NONE, choose, never_renders, renders


def _installed(*libraries: str) -> object:
    return lambda name: f"lib{name}.so.1" if name in libraries else None


def test_a_platform_the_user_set_is_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ctypes.util, "find_library", _installed())
    env = {"MUJOCO_GL": "osmesa"}
    assert choose(env) == "osmesa" and env == {"MUJOCO_GL": "osmesa"}


@pytest.mark.parametrize(
    ("libraries", "chosen"),
    [(("EGL", "OSMesa"), "egl"), (("OSMesa",), "osmesa"), ((), NONE)],
)
def test_the_first_installed_library_is_chosen(
    libraries: tuple[str, ...], chosen: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(ctypes.util, "find_library", _installed(*libraries))
    env: dict[str, str] = {}
    assert choose(env) == chosen == env["MUJOCO_GL"]
    assert renders(env) is (chosen != NONE)


def test_a_process_that_never_renders_imports_mujoco_without_a_gl_platform() -> None:
    """The world process and ag_ex's loop: ``never_renders`` before MuJoCo's first import
    leaves out its GL platform (PyOpenGL)."""
    code = (
        "import os, sys\n"
        "from velma.gl import never_renders\n"
        "first = never_renders()\n"
        "import mujoco\n"
        "print(first, os.environ['MUJOCO_GL'], 'OpenGL' in sys.modules)\n"
    )
    env = {**os.environ, "MUJOCO_GL": "egl"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", NONE, "False"]


def test_once_mujoco_is_imported_never_renders_changes_nothing() -> None:
    import mujoco  # noqa: F401  (its platform is chosen)

    env = {"MUJOCO_GL": "egl"}
    assert never_renders(env) is False and env == {"MUJOCO_GL": "egl"}


def test_without_a_gl_platform_mujoco_still_simulates() -> None:
    """``MUJOCO_GL=egl`` where libEGL is missing breaks ``import mujoco``; ``disable`` does not."""
    code = (
        "import mujoco\n"
        "from velma.model.scene import N_PARTICLES, load_kitchen\n"
        "m = load_kitchen(N_PARTICLES)\n"
        "d = mujoco.MjData(m)\n"
        "mujoco.mj_step(m, d)\n"
        "print(d.time)\n"
    )
    env = {**os.environ, "MUJOCO_GL": NONE}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) > 0.0


def test_without_a_gl_platform_the_robot_perceives_with_the_truth(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MUJOCO_GL", NONE)
    assert perception_mode({}) == "truth" == perception_mode({"ROCO_PERCEPTION": ""})
    assert perception_mode({"ROCO_PERCEPTION": "camera"}) == "camera"  # asked for: the CLI refuses it
    why = camera_unavailable()
    assert why is not None and HOW in why
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert camera_unavailable() is None and perception_mode({}) == DEFAULT_PERCEPTION == "camera"
