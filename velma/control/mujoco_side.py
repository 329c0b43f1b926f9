"""Whether the compiled module's MuJoCo side (``Plant`` of velma/control/_plant.hpp) can run
here, and whether it is wanted (``ROCO_PLANT``). Both ag_ex's loop (velma/executor/plant.py)
and the world process (velma/world/hardware.py) step MuJoCo through it.

The ``Plant`` uses MuJoCo through its headers only: it needs the ``mjData`` layout of the
headers it was built with (setup.py takes them from the ``mujoco`` wheel of the build), so it
runs only when the running ``mujoco`` is that version, and it calls the ``mj_step`` of the
libmujoco that the ``mujoco`` module loaded.
"""

from __future__ import annotations

import ctypes
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco

from shared.settings import Settings
from velma.control import hand
from velma.control.hand import ContactMonitor, Hands
from velma.control.joints import SIDES, Array, JointMap
from velma.control.native import native_module

ENV_PLANT = Settings.env_name("plant")
"""Environment variable: ``compiled`` requires the compiled plant (an error if it cannot
run), ``python`` runs the Python cycle; unset: the compiled plant where it can run
(``mujoco_side_unavailable``), else the Python cycle with a warning."""


def plant_choice(environ: Mapping[str, str] | None = None) -> bool | None:
    """``ROCO_PLANT`` as a choice: True (the compiled plant, required), False (the Python
    cycle) or None (unset: the compiled plant where it can run). The compiled plant is the
    default since the loop holds the CPUs' wake-up latency (docs/bench/loop.md "CPU latency PM
    QoS"): with the whole fleet it gave the lower cycle work at p50 and p99 and overran as
    rarely as the Python cycle. Raises ValueError for a value other than ``python`` and
    ``compiled``. ``environ``: default ``os.environ``, read now."""
    choice = Settings.from_env(environ, only=("plant",)).plant
    return None if choice is None else choice == "compiled"


def mj_step_address() -> int | None:
    """The address of ``mj_step`` in the libmujoco that the ``mujoco`` module loaded (the
    same file: the dynamic loader gives back the loaded library), or None when there is no
    such file beside the module."""
    folder = Path(mujoco.__file__).parent
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        for lib in sorted(folder.glob(pattern)):
            address = ctypes.cast(ctypes.CDLL(str(lib)).mj_step, ctypes.c_void_p).value
            if address:
                return int(address)
    return None


def mujoco_side_unavailable() -> str | None:
    """Why the compiled ``Plant`` cannot run here (module docstring), or None when it can."""
    native = native_module()
    if native is None:
        return "the compiled module is not built"
    built = getattr(native, "MUJOCO_HEADER_VERSION", None)
    if built is None:
        return "the compiled module was built without MuJoCo's headers"
    if int(built) != mujoco.mj_version():
        return f"built with MuJoCo headers {built}, running MuJoCo {mujoco.mj_version()}"
    if mj_step_address() is None:
        return "no libmujoco beside the mujoco module"
    return None


def make_plant(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    jmap: JointMap,
    contacts: ContactMonitor,
    arm_act: list[int],
    torso_act: int,
) -> Any:
    """A C++ ``Plant`` on ``model`` and ``data`` (kept alive by it): ``jmap`` maps Pinocchio's
    joints to MuJoCo's, ``contacts`` says which geoms are a hand's or the robot's, ``arm_act``
    the 14 arm motors (right, then left), ``torso_act`` the torso's. Raises RuntimeError when
    ``mujoco_side_unavailable`` gives a reason, ValueError on indices that do not fit."""
    why = mujoco_side_unavailable()
    if why is not None:
        raise RuntimeError(f"no compiled plant: {why}")
    native, step = native_module(), mj_step_address()
    assert native is not None and step is not None
    return native.Plant(
        model,
        data,
        step,
        jmap.qpos_adr.tolist(),
        jmap.dof_adr.tolist(),
        arm_act,
        torso_act,
        contacts.hand_side.tolist(),
        contacts.part.tolist(),
        contacts.robot_body.astype(int).tolist(),
    )


def bind_servos(
    plant: Any, hands: Hands, head: Array, head_act: tuple[int, int], *, dt: float, head_step: float
) -> None:
    """Have ``plant`` step the hands' and the head's servo setpoints, in C++ as
    velma/control/hand.py ``Hands.step`` does with ``dt`` (s) and velma/world/hardware.py
    ``ramp`` with ``head_step`` (rad, the most a setpoint moves in one cycle): on
    ``hands.state`` and ``head`` (4,) float64 (pan and tilt setpoints, then targets; rad), with
    ``head_act`` the pan and tilt servos. Both arrays are bound, not copied: assign into them,
    never rebind them. Raises ValueError on sizes or indices that do not fit."""
    plant.bind_servos(
        hands.state,
        head,
        [int(a) for s in SIDES for a in hands.spread_act[s]],
        [int(a) for s in SIDES for a in hands.prox_act[s]],
        [int(a) for s in SIDES for a in hands.dist_act[s]],
        [int(a) for s in SIDES for a in hands.prox_q[s]],
        [float(k) for s in SIDES for k in hands.prox_kp[s]],
        [int(a) for a in head_act],
        [
            dt,
            hand.BREAKAWAY_TORQUE,
            hand.CLOSE_RATE,
            hand.OPEN_RATE,
            hand.SPREAD_RATE,
            hand.DISTAL_RATIO,
            hand.DISTAL_MAX,
            head_step,
        ],
    )
