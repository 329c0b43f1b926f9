"""Snapshots of the simulated world held by a ``Runtime`` (the physics in this process): capture
and restore, exactly, so that tests and tools can set a scene up where a run got to (a hand at
the jar's grasp pose, a jar lifted, a tilt begun) and judge a world a run left.

What a checkpoint holds (``Checkpoint``, one msgpack record):

- MuJoCo's whole integration state, ``mj_getState(…, mjSTATE_INTEGRATION)``: time, qpos and
  qvel (robot, jar, bowl, cup and every content sphere), actuator activations, the solver's
  warm start, ctrl, applied forces, mocap and equality-constraint states;
- what lies outside MjData and matters (``LAYOUT``): each arm's setpoint (mode, Cartesian pose,
  twist, stiffness, null-space posture, joint setpoint and stiffness), the previous cycle's
  torques (the torque rate limit's memory), the torso setpoint, each hand's controller state
  (spread, proximal/distal setpoints and targets, which clutches broke away), the head's
  setpoint and target, the loop's cycle count and, per hand, which object it holds (by body
  name) and for how many contact scans it has not touched it;
- why the loop held position (``holding``) and a ``Fingerprint`` of the model (sizes and the
  SHA-256 of the compiled model, MJB): a checkpoint of another model or scene (other seed,
  other pose seed, other number of content spheres) is refused (``CheckpointError``).

``Capture.take`` encodes one, ``decode`` checks and decodes it, ``apply`` sets a ``Runtime`` to
it and ``resume`` makes its loop hold position there. A restored world continues as the
original would (qpos within 1e-9, tests/velma/test_checkpoint.py). ag_ex's restarts need none
of this: the kitchen lives in the world process (velma/world/), which outlives the controller.
``observe_scene`` judges the scene a world process left when it ended.
"""

from __future__ import annotations

import hashlib
import math
import time
from typing import TYPE_CHECKING, Any

import msgspec
import numpy as np

from velma.control.joints import SIDES
from velma.control.payload import Payload
from velma.executor.payloads import SOURCES as LOAD_SOURCES
from velma.executor.payloads import STATE_SIZE as LOAD_STATE_SIZE

if TYPE_CHECKING:
    import mujoco

    from shared.fipa_codec.languages.l_sd import Observation
    from velma.executor.loop import ControlLoop
    from velma.executor.runtime import Runtime

FORMAT = "roco-ex-checkpoint/1"
RESTART_WHY = "ag_ex restarted"  # the loop's ``holding`` after ``resume``
MODES = ("joint", "cart", "safe")  # ArmCommand.mode, as a number in the checkpoint


# ---------------------------------------------------------------------- the file
class Fingerprint(msgspec.Struct, frozen=True):
    """What must be equal for a checkpoint to fit a model: its sizes, the length of MuJoCo's
    integration state and the SHA-256 of the compiled model (MJB: geometry, masses, joints,
    actuators, options and the initial poses, so also the scene's seeds)."""

    nq: int
    nv: int
    na: int
    nu: int
    nbody: int
    nstate: int
    model_sha256: str

    def differences(self, other: Fingerprint) -> list[str]:
        """``"name mine ≠ other"`` for every field that differs."""
        out = []
        for name in self.__struct_fields__:
            a, b = getattr(self, name), getattr(other, name)
            if a != b:
                if name == "model_sha256":
                    a, b = a[:12], b[:12]
                out.append(f"{name} {a} ≠ {b}")
        return out


def _state_sig() -> int:
    import mujoco

    return int(mujoco.mjtState.mjSTATE_INTEGRATION)


def fingerprint(model: mujoco.MjModel) -> Fingerprint:
    """The ``Fingerprint`` of ``model`` (≈ 1 ms: the model is serialised once)."""
    import mujoco

    mjb = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, mjb)
    return Fingerprint(
        nq=model.nq,
        nv=model.nv,
        na=model.na,
        nu=model.nu,
        nbody=model.nbody,
        nstate=int(mujoco.mj_stateSize(model, _state_sig())),
        model_sha256=hashlib.sha256(mjb.tobytes()).hexdigest(),
    )


def _layout() -> tuple[tuple[str, int], ...]:
    fields: list[tuple[str, int]] = []
    for s in SIDES:
        fields += [
            (f"{s}.arm.mode", 1),  # index in MODES
            (f"{s}.arm.rotation", 9),  # Cartesian setpoint, world, row-major
            (f"{s}.arm.translation", 3),  # m
            (f"{s}.arm.twist", 6),
            (f"{s}.arm.stiffness", 6),
            (f"{s}.arm.posture", 7),
            (f"{s}.arm.q", 7),
            (f"{s}.arm.qd", 7),
            (f"{s}.arm.joint_stiffness", 7),
            (f"{s}.arm.prev_torque", 7),  # NaN: none yet
            (f"{s}.hand.spread", 2),  # setpoint, target
            (f"{s}.hand.proximal", 3),
            (f"{s}.hand.target", 3),
            (f"{s}.hand.distal", 3),
            (f"{s}.hand.broken", 3),  # 0/1
            (f"{s}.lost_cycles", 1),
            (f"{s}.load", LOAD_STATE_SIZE),  # velma/executor/payloads.py HeldLoads.pack
        ]
    fields += [
        ("torso", 3),  # setpoint, setpoint rate, previous torque (NaN: none yet)
        ("head", 4),  # setpoint pan/tilt, target pan/tilt
        ("cycles", 1),
    ]
    return tuple(fields)


LAYOUT = _layout()
"""The controller part of a checkpoint: (field, number of float64) in order."""


class Checkpoint(msgspec.Struct, frozen=True, kw_only=True):
    """One checkpoint of the simulated world (see module docstring). ``physics``: float64
    ``mj_getState`` with signature ``state_sig``; ``controller``: float64 in ``layout``;
    ``wall_time``: ``time.time()`` when it was taken; ``held``: the body each hand holds."""

    format: str
    fingerprint: Fingerprint
    layout: tuple[tuple[str, int], ...]
    state_sig: int
    sim_time: float
    wall_time: float
    physics: bytes
    controller: bytes
    holding: str | None
    held: dict[str, str | None]


def _views(buf: np.ndarray) -> dict[str, np.ndarray]:
    out, at = {}, 0
    for name, n in LAYOUT:
        out[name] = buf[at : at + n]
        at += n
    return out


def _layout_size() -> int:
    return sum(n for _, n in LAYOUT)


class Capture:
    """Takes checkpoints of ``rt`` in the loop process: ``take`` copies MjData's integration
    state and the controllers' state into preallocated arrays and encodes them (no file I/O;
    see docs/executor.md for its cost)."""

    def __init__(self, rt: Runtime, fp: Fingerprint | None = None) -> None:
        self.rt = rt
        self.fp = fp if fp is not None else fingerprint(rt.model)
        self.sig = _state_sig()
        self.physics = np.zeros(self.fp.nstate)
        self.controller = np.zeros(_layout_size())
        self.views = _views(self.controller)
        self.body_names = tuple(rt.model.body(b).name for b in range(rt.model.nbody))
        self._encode = msgspec.msgpack.Encoder().encode

    def take(self, holding: str | None) -> bytes:
        """The checkpoint of the world now, encoded (``Checkpoint``)."""
        import mujoco

        rt = self.rt
        mujoco.mj_getState(rt.model, rt.data, self.physics, self.sig)
        _pack(rt, self.views)
        names = self.body_names
        return self._encode(
            Checkpoint(
                format=FORMAT,
                fingerprint=self.fp,
                layout=LAYOUT,
                state_sig=self.sig,
                sim_time=float(rt.data.time),
                wall_time=time.time(),
                physics=self.physics.tobytes(),
                controller=self.controller.tobytes(),
                holding=holding,
                held={s: (names[b] if (b := rt.held[s]) is not None else None) for s in SIDES},
            )
        )


def _pack(rt: Runtime, v: dict[str, np.ndarray]) -> None:
    # the torque rate limit's memory is the controller's private state (velma.control.impedance):
    # read and restored here, the one place outside the controller that needs it
    ctrl = rt.ctrl
    prev = ctrl._prev_arm
    for k, s in enumerate(SIDES):
        a = ctrl.arm[s]
        v[f"{s}.arm.mode"][0] = MODES.index(a.mode)
        v[f"{s}.arm.rotation"][:] = a.pose.rotation.ravel()
        v[f"{s}.arm.translation"][:] = a.pose.translation
        v[f"{s}.arm.twist"][:] = a.twist
        v[f"{s}.arm.stiffness"][:] = a.stiffness
        v[f"{s}.arm.posture"][:] = a.posture
        v[f"{s}.arm.q"][:] = a.q
        v[f"{s}.arm.qd"][:] = a.qd
        v[f"{s}.arm.joint_stiffness"][:] = a.joint_stiffness
        v[f"{s}.arm.prev_torque"][:] = prev[k] if prev is not None else math.nan
        h = rt.hands.set[s]
        v[f"{s}.hand.spread"][:] = (h.spread, h.spread_target)
        v[f"{s}.hand.proximal"][:] = h.proximal
        v[f"{s}.hand.target"][:] = h.target
        v[f"{s}.hand.distal"][:] = h.distal
        v[f"{s}.hand.broken"][:] = h.broken
        v[f"{s}.lost_cycles"][0] = rt.lost_cycles[s]
        v[f"{s}.load"][:] = rt.loads.pack(s)
    prev_torso = ctrl._prev_torso
    v["torso"][:] = (ctrl.torso_q, ctrl.torso_qd, math.nan if prev_torso is None else prev_torso)
    v["head"][:2] = rt.head_set
    v["head"][2:] = rt.head_target
    v["cycles"][0] = rt.cycles


def _unpack(rt: Runtime, v: dict[str, np.ndarray]) -> None:
    import pinocchio as pin

    ctrl = rt.ctrl
    prev = np.empty((len(SIDES), 7))
    for k, s in enumerate(SIDES):
        a = ctrl.arm[s]
        a.mode = MODES[int(v[f"{s}.arm.mode"][0])]
        a.pose = pin.SE3(v[f"{s}.arm.rotation"].reshape(3, 3).copy(), v[f"{s}.arm.translation"].copy())
        a.twist = v[f"{s}.arm.twist"].copy()
        a.stiffness = v[f"{s}.arm.stiffness"].copy()
        a.posture = v[f"{s}.arm.posture"].copy()
        a.q = v[f"{s}.arm.q"].copy()
        a.qd = v[f"{s}.arm.qd"].copy()
        js = v[f"{s}.arm.joint_stiffness"]
        a.joint_stiffness = float(js[0]) if np.all(js == js[0]) else js.copy()
        prev[k] = v[f"{s}.arm.prev_torque"]
        h = rt.hands.set[s]
        h.spread, h.spread_target = (float(x) for x in v[f"{s}.hand.spread"])
        h.proximal = v[f"{s}.hand.proximal"].copy()
        h.target = v[f"{s}.hand.target"].copy()
        h.distal = v[f"{s}.hand.distal"].copy()
        h.broken = v[f"{s}.hand.broken"] != 0.0
        h.steady = False  # the next step writes the restored setpoints into data.ctrl
        rt.lost_cycles[s] = int(v[f"{s}.lost_cycles"][0])
    ctrl._prev_arm = None if np.isnan(prev).any() else prev
    torso_q, torso_qd, prev_torso = (float(x) for x in v["torso"])
    ctrl.torso_q, ctrl.torso_qd = torso_q, torso_qd
    ctrl._prev_torso = None if math.isnan(prev_torso) else prev_torso
    rt.head_set = v["head"][:2].copy()
    rt.head_target = v["head"][2:].copy()
    rt.cycles = int(v["cycles"][0])


class CheckpointError(ValueError):
    """A checkpoint that cannot be used: unreadable, another format, another model."""


def decode(raw: bytes, fp: Fingerprint) -> Checkpoint:
    """The checkpoint in ``raw`` if it fits a model with fingerprint ``fp``; raises
    ``CheckpointError`` saying why not."""
    try:
        ckpt = msgspec.msgpack.decode(raw, type=Checkpoint)
    except msgspec.DecodeError as exc:
        raise CheckpointError(f"unreadable ({exc})") from None
    if ckpt.format != FORMAT:
        raise CheckpointError(f"format {ckpt.format!r}, expected {FORMAT!r}")
    if ckpt.fingerprint != fp:
        diff = "; ".join(ckpt.fingerprint.differences(fp))
        raise CheckpointError(f"made for another model or scene (checkpoint ≠ this loop: {diff})")
    if tuple(tuple(f) for f in ckpt.layout) != LAYOUT or ckpt.state_sig != _state_sig():
        raise CheckpointError("another layout of the controller or physics state")
    if len(ckpt.physics) != 8 * fp.nstate or len(ckpt.controller) != 8 * _layout_size():
        raise CheckpointError("truncated state")
    return ckpt


def _check_load(side: str, load: np.ndarray) -> None:
    """Raise ``CheckpointError`` unless ``load`` (``HeldLoads.pack``) is a load a hand can hold."""
    if int(load[4]) not in range(len(LOAD_SOURCES)):
        raise CheckpointError(f"{side} hand's load from an unknown source {load[4]}")
    try:
        Payload(float(load[0]), (float(load[1]), float(load[2]), float(load[3])))
    except ValueError as exc:
        raise CheckpointError(f"{side} hand: {exc}") from None


def apply(rt: Runtime, ckpt: Checkpoint) -> None:
    """Put ``rt`` into the state of ``ckpt`` (which ``decode`` accepted for ``rt.model``):
    physics, controllers and held objects exactly as they were; the arm setpoints too (a
    host then usually calls ``resume``). Raises ``CheckpointError`` for a held body the model
    does not have."""
    import mujoco

    held: dict[str, int | None] = {}
    for s in SIDES:
        name = ckpt.held.get(s)
        if name is None:
            held[s] = None
            continue
        b = mujoco.mj_name2id(rt.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if b < 0:
            raise CheckpointError(f"held body {name!r} is not in the model")
        held[s] = int(b)
    controller = _views(np.frombuffer(ckpt.controller, dtype=np.float64).copy())
    for name, values in controller.items():  # NaN only where it means "none yet"
        if name.endswith("prev_torque") or name == "torso":
            values = values[~np.isnan(values)]
        if not np.all(np.isfinite(values)):
            raise CheckpointError(f"non-finite controller state ({name})")
    for s in SIDES:
        if controller[f"{s}.arm.mode"][0] not in range(len(MODES)):
            raise CheckpointError(f"{s} arm in an unknown mode {controller[f'{s}.arm.mode'][0]}")
        _check_load(s, controller[f"{s}.load"])
    physics = np.frombuffer(ckpt.physics, dtype=np.float64).copy()
    if not np.all(np.isfinite(physics)):
        raise CheckpointError("non-finite physics state")
    mujoco.mj_setState(rt.model, rt.data, physics, ckpt.state_sig)
    mujoco.mj_forward(rt.model, rt.data)
    _unpack(rt, controller)
    rt.held.update(held)
    for s in SIDES:
        rt.loads.unpack(s, controller[f"{s}.load"].tolist(), held[s])
    q, v = rt.q(), rt.v()
    rt.ctrl.kinematics(q, v)
    for s in SIDES:
        rt.ctrl.state[s].grip = rt.ctrl.grip_pose(s)


def resume(loop: ControlLoop[Any], ckpt: Checkpoint) -> None:
    """After ``apply``: hold position at the restored setpoints, frozen: each arm stays in its
    mode (joint, Cartesian or safe impedance) at its setpoint with zero velocity feed-forward,
    the torso at its setpoint, the head at its current setpoint, the hands' setpoints as they
    were. The published state says ``holding: "ag_ex restarted"`` (a loop in safe mode keeps
    its safe-mode reason) until the next command.

    Why not ``ControlLoop.hold`` (joint impedance at the measured joint positions): an arm
    carrying the jar in Cartesian impedance has a steady error that carries the payload; a new
    joint setpoint at the measured position drops that load onto the joint springs, and the jar
    sank 11 mm in 2 s (measured, the jar lifted 10 cm); the restored setpoint keeps the spring
    where it was (0.06 mm)."""
    rt = loop.rt
    for side in SIDES:
        cmd = rt.ctrl.arm[side]
        cmd.twist = np.zeros(6)
        cmd.qd = np.zeros(7)
    rt.ctrl.torso_qd = 0.0
    rt.head_target = rt.head_set.copy()
    safe = ckpt.holding is not None and ckpt.holding.startswith("safe mode: ")
    loop.holding = ckpt.holding if safe else RESTART_WHY


def observe_scene(values: bytes, *, seed: int = 0, pose_seed: int | None = None) -> Observation:
    """The ground truth of a kitchen saved as raw float64 (the time, then MuJoCo's ``qpos``: a
    world process's final scene, velma/world/files.py ``FINAL_FILE``) for the scene of ``seed``
    and ``pose_seed``: for judging a run, never for the agents. Raises ValueError when the
    values do not fit that scene."""
    import mujoco

    from velma.executor.ground_truth import GroundTruth
    from velma.model.scene import N_PARTICLES, load_kitchen

    model = load_kitchen(N_PARTICLES, seed, pose_seed)
    scene = np.frombuffer(values, dtype=np.float64)
    if scene.size != 1 + model.nq:
        raise ValueError(f"{scene.size - 1} coordinates for a kitchen of {model.nq}")
    data = mujoco.MjData(model)
    data.time, data.qpos[:] = scene[0], scene[1:]
    mujoco.mj_kinematics(model, data)
    return GroundTruth(model).observe(data)
