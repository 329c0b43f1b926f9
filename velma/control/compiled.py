"""The impedance control law compiled: ``CompiledController`` computes, in C++, exactly what
``VelmaController.update`` computes in Python (velma/control/impedance.py, whose module
docstring states the laws and their sources).

The C++ code (``velma/control/_impedance.cpp``, built by ``pip install`` with pybind11 against
Pinocchio's own headers, those of the ``pin`` wheel) rebuilds the Pinocchio model from the
numbers of ``RobotModel.model``: every joint's kind and axis, placement, inertia, armature
and limits, and the two grip frames. The Python class stays the reference:
tests/velma/test_compiled_law.py compares the torques of both over random states in every
mode, and the simulated robot's motion with each over 0.3 s of closed loop.

``make_controller`` picks the law: the compiled one when the extension is built, else the
Python one (with a warning); ``ROCO_CONTROL_LAW=python`` forces the Python law (for
comparisons, e.g. ``scripts/bench_controller.py``).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pinocchio as pin

from shared.settings import Settings
from velma.control import impedance as imp
from velma.control.ik import DlsKernel
from velma.control.joints import SIDES, Array
from velma.control.limits import ARM_TORQUE_LIMIT, FULL_BAND_JOINTS, SINGULAR_JOINTS, TORQUE_RATE_LIMIT
from velma.control.native import IMPORT_ERROR as _IMPORT_ERROR
from velma.control.native import extension as _impedance
from velma.control.payload import Payload
from velma.control.robot_model import RobotModel
from velma.control.self_collision import WRIST_BAND, WRIST_BAND_DAMPING, WRIST_BAND_TORQUE, WristField

log = logging.getLogger(__name__)


ENV_LAW = Settings.env_name("control_law")
"""Environment variable: ``python`` forces the Python law, ``compiled`` requires the compiled
one (an error if it is not built); unset: the compiled one when built."""

_MODE = {mode: k for k, mode in enumerate(imp.MODES)}  # kCart, kJoint, kSafe of _impedance.cpp
_JOINT_KIND = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2, "JointModelRevoluteUnaligned": 3}
# the command row of one arm (the layout of _impedance.cpp)
_ROT, _POS, _TWIST, _STIFF, _POSTURE, _Q, _QD, _KJ, _LOAD, _WIDTH = 1, 10, 13, 19, 25, 32, 39, 46, 53, 57


def compiled_available() -> bool:
    """Whether the compiled law was built (and imports)."""
    return _impedance is not None


def _build_law(robot: RobotModel, dt: float, torso_idx: int, arm_v0: list[int]) -> _impedance.Law:
    """The C++ ``Law`` with ``robot``'s model. Raises ``ValueError`` for a joint kind other
    than a revolute one (Velma has only revolute joints)."""
    assert _impedance is not None
    model = robot.model
    law = _impedance.Law()
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = _JOINT_KIND.get(joint.shortname())
        if kind is None:
            raise ValueError(f"{model.names[j]}: the compiled law has no {joint.shortname()}")
        axis = [float(a) for a in joint.extract().axis] if kind == 3 else [0.0, 0.0, 0.0]
        placement = model.jointPlacements[j]
        body = model.inertias[j]
        inertia = body.inertia
        law.add_joint(
            int(model.parents[j]),
            kind,
            axis,
            [float(x) for x in placement.rotation.flatten()],
            [float(x) for x in placement.translation],
            float(body.mass),
            [float(x) for x in body.lever],
            [float(inertia[i, j]) for i, j in ((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2))],
            float(model.armature[joint.idx_v]),
            float(model.lowerPositionLimit[joint.idx_q]),
            float(model.upperPositionLimit[joint.idx_q]),
            model.names[j],
        )
    for side in SIDES:
        frame = model.frames[robot.grip_frame_id[side]]
        law.add_grip(
            int(frame.parentJoint),
            [float(x) for x in frame.placement.rotation.flatten()],
            [float(x) for x in frame.placement.translation],
            frame.name,
        )
    constants = [
        dt,
        imp.DAMPING_RATIO,
        imp.SAFE_STIFFNESS,
        imp.SAFE_DAMPING_RATIO,
        imp.TORSO_STIFFNESS,
        imp.NULLSPACE_STIFFNESS,
        imp.NULLSPACE_DAMPING,
        imp.LAMBDA_REGULARISATION,
        TORQUE_RATE_LIMIT,
        imp.TORSO_TORQUE_LIMIT,
        *[float(x) for x in ARM_TORQUE_LIMIT],
        *[1.0 if i in FULL_BAND_JOINTS else 0.0 for i in range(7)],
        *[1.0 if i in SINGULAR_JOINTS else 0.0 for i in range(7)],
    ]
    law.finish(arm_v0, torso_idx, constants)
    return law


class _PlantArmState(imp.ArmState):
    """``ArmState`` of a controller stepped by a compiled plant: the grip pose and the torque
    are read from the law's output row (``row``, (32,), the layout of _impedance.cpp) when
    asked, not built every cycle (the cycle's budget); ``refresh`` marks a new row.
    Assigning ``grip`` or ``torque`` sets them until the next ``refresh``."""

    def __init__(self, row: Array, now: imp.ArmState) -> None:
        self._row = row
        self._grip: pin.SE3 | None = now.grip
        self._torque: Array | None = now.torque
        self.error = now.error

    def refresh(self) -> None:
        self._grip = None
        self._torque = None

    @property
    def grip(self) -> pin.SE3:
        if self._grip is None:
            self._grip = pin.SE3(self._row[14:23].reshape(3, 3), self._row[23:26])
        return self._grip

    @grip.setter
    def grip(self, value: pin.SE3) -> None:
        self._grip = value

    @property
    def torque(self) -> Array:
        if self._torque is None:
            self._torque = self._row[0:7].copy()
        return self._torque

    @torque.setter
    def torque(self, value: Array) -> None:
        self._torque = value


class CompiledController(imp.VelmaController):
    """``VelmaController`` whose ``update`` runs in C++ (module docstring); everything else
    (commands, modes, ``hold``, ``safe``, ``limits``, ``state``, the checkpointed rate-limit
    state) is the Python class's. Raises ``RuntimeError`` if the extension is not built."""

    def __init__(self, robot: RobotModel, dt: float = 0.001) -> None:
        if _impedance is None:
            raise RuntimeError(f"the compiled control law is not built ({_IMPORT_ERROR})")
        super().__init__(robot, dt)
        self._law = _build_law(robot, dt, self.torso_idx, [int(self.arm_idx[s][0]) for s in SIDES])
        self._wrist_of: WristField | None = None
        self._send_wrist()
        self._cmd = np.zeros((2, _WIDTH))
        self._payload_of: list[Payload | None] = [None, None]  # the payloads in _cmd's rows
        self._torso_in = np.zeros(3)
        self._prev_in = np.zeros((2, 7))
        self._limits_in = np.zeros(10)
        self._limits_of: imp.SafetyLimits | None = None
        self._out = np.zeros((2, 32))
        self._out_torso = np.zeros(2)
        self._plant_states: list[_PlantArmState] = []  # ``state`` once bound to a plant

    @property
    def ik_kernel(self) -> DlsKernel:
        """The IK's damped-least-squares iteration in C++ on this law's model (its own
        Pinocchio data): velma/control/ik.py ``DlsKernel``."""
        law: DlsKernel = self._law
        return law

    def _send_wrist(self) -> None:
        """Give the C++ law the wrist band's table (``self.wrist``; None: an empty table, the
        band off)."""
        field = self.wrist
        if field is None:
            self._law.set_wrist(0.0, 0.0, 1.0, 2, 2, [1.0] * 8, 0.0, 0.0, 0.0)  # d = 1 m: never in the band
        else:
            _, n5, n6 = field.distance.shape
            self._law.set_wrist(
                field.lower[0],
                field.lower[1],
                field.step,
                n5,
                n6,
                [float(x) for x in field.distance.reshape(-1)],
                WRIST_BAND,
                WRIST_BAND_TORQUE,
                WRIST_BAND_DAMPING,
            )
        self._wrist_of = field

    def update(self, q: Array, v: Array) -> tuple[dict[str, Array], float]:
        """As ``VelmaController.update`` (same arguments, result, state and errors)."""
        cart = self._pack()
        q = np.ascontiguousarray(q, dtype=float)
        v = np.ascontiguousarray(v, dtype=float)
        try:
            self._law.update(
                q, v, self._cmd, self._torso_in, self._prev_in, self._limits_in, self._out, self._out_torso
            )
        except ArithmeticError as exc:
            raise np.linalg.LinAlgError(str(exc)) from exc
        return self._absorb(q, cart), float(self._out_torso[0])

    def bind_plant(self, plant: _impedance.Plant, q: Array, v: Array, parts: Array) -> None:
        """Give ``plant`` (velma/control/_plant.hpp) this law and its input and output arrays,
        once: ``q``, ``v`` (nv,) float64 receive the state the law used in each cycle,
        ``parts`` (2,) the seconds of the law (with the gather) and of the step. From then on
        ``state`` reads the grip poses and torques from the law's output when asked. Raises
        TypeError for arrays of another dtype or layout, ValueError for other sizes."""
        self._plant_states = [_PlantArmState(self._out[k], self.state[s]) for k, s in enumerate(SIDES)]
        self.state = dict(zip(SIDES, self._plant_states, strict=True))
        plant.bind(
            self._law,
            self._cmd,
            self._torso_in,
            self._prev_in,
            self._limits_in,
            self._out,
            self._out_torso,
            q,
            v,
            parts,
        )

    def step_plant(self, plant: _impedance.Plant, q: Array) -> None:
        """One cycle of ``plant`` bound by ``bind_plant`` (``Plant.cycle``): the law on MuJoCo's
        state, the torques into its ctrl, one mj_step; ``q`` is the array bound as q. The
        controller's state afterwards is that of ``update`` (its grip poses and torques read
        when asked); raises as ``update``."""
        cart = self._pack()
        try:
            plant.cycle()
        except ArithmeticError as exc:
            raise np.linalg.LinAlgError(str(exc)) from exc
        out = self._out
        self._q_arm = q[self._idx]
        self._prev_arm = out[:, 7:14].copy()
        self._prev_torso = float(self._out_torso[1])
        for k, state in enumerate(self._plant_states):
            state.refresh()
            if cart[k]:
                state.error = out[k, 26:32].copy()

    def _pack(self) -> list[bool]:
        """Write the arms' commands, the torso's and the limits into the law's input arrays;
        returns which arms are in Cartesian mode. Raises ValueError for an unknown mode."""
        if self.wrist is not self._wrist_of:
            self._send_wrist()
        cmd = self._cmd
        cart = [False, False]
        for k, side in enumerate(SIDES):
            a = self.arm[side]
            mode = _MODE.get(a.mode)
            if mode is None:
                raise ValueError(f"{side} arm: unknown mode {a.mode!r} (expected one of {imp.MODES})")
            row = cmd[k]
            row[0] = mode
            cart[k] = mode == 0
            if cart[k]:
                row[_ROT:_POS] = a.pose.rotation.reshape(9)
                row[_POS:_TWIST] = a.pose.translation
                row[_TWIST:_STIFF] = a.twist
                row[_STIFF:_POSTURE] = a.stiffness
                row[_POSTURE:_Q] = a.posture
            else:
                row[_Q:_QD] = a.q
                row[_QD:_KJ] = a.qd
                row[_KJ:_LOAD] = a.joint_stiffness
            load = self.payload[side]
            if load is not self._payload_of[k]:  # mass, then the centre of mass (payload.py)
                row[_LOAD] = load.mass
                row[_LOAD + 1 : _WIDTH] = load.com
                self._payload_of[k] = load
        if self.limits is not self._limits_of:
            lim = self.limits
            self._limits_in[:] = (
                lim.limit_band,
                lim.limit_band_torque,
                lim.singularity_half_width,
                lim.singularity_band,
                lim.singularity_band_torque,
                lim.band_damping_ratio,
                lim.null_space_band_scale,
                lim.arm_velocity,
                lim.torso_velocity,
                lim.velocity_time_constant,
            )
            self._limits_of = lim
        prev = self._prev_arm
        if prev is None:
            self._prev_in[:] = math.nan
        else:
            self._prev_in[:] = prev
        self._torso_in[0] = self.torso_q
        self._torso_in[1] = self.torso_qd
        self._torso_in[2] = math.nan if self._prev_torso is None else self._prev_torso
        return cart

    def _absorb(self, q: Array, cart: list[bool]) -> dict[str, Array]:
        """Take the law's outputs into the controller's state (as the Python law leaves it);
        returns the arm torques by side."""
        out = self._out
        self._q_arm = q[self._idx]
        self._prev_arm = out[:, 7:14].copy()
        self._prev_torso = float(self._out_torso[1])
        torques = {}
        for k, side in enumerate(SIDES):
            state = self.state[side]
            state.grip = pin.SE3(out[k, 14:23].reshape(3, 3), out[k, 23:26])
            if cart[k]:
                state.error = out[k, 26:32].copy()
            torque = out[k, 0:7].copy()
            state.torque = torque
            torques[side] = torque
        return torques


def law_name(ctrl: imp.VelmaController) -> str:
    """``compiled`` or ``python``: which law ``ctrl`` runs (for the loop's timing report)."""
    return "compiled" if isinstance(ctrl, CompiledController) else "python"


def make_controller(robot: RobotModel, dt: float = 0.001) -> imp.VelmaController:
    """The control law to run: compiled when built (unless ``ROCO_CONTROL_LAW=python``), else
    the Python reference with a warning. Raises ``RuntimeError`` when ``ROCO_CONTROL_LAW=compiled``
    and the extension is not built, ``ValueError`` for another value of it."""
    choice = Settings.from_env(only=("control_law",)).control_law  # ValueError: another value
    if choice == "python":
        return imp.VelmaController(robot, dt)
    if _impedance is None:
        if choice == "compiled":
            raise RuntimeError(f"{ENV_LAW}=compiled, but the compiled law is not built ({_IMPORT_ERROR})")
        log.warning("the compiled control law is not built (%s): running the Python law", _IMPORT_ERROR)
        return imp.VelmaController(robot, dt)
    return CompiledController(robot, dt)
