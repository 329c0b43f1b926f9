"""Checkpoint and restore of the simulated world, so that restarting ag_ex does not reset the
kitchen ("any one service restarted at any moment of a pour run, and the task still
completes"; a real robot's world does not go back to its initial scene either).

What a checkpoint holds (``Checkpoint``, one msgpack file ``<dir>/world.ckpt``):

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
  other pose seed, other number of content spheres) is refused.

Who does what:

- the loop process (velma.executor.process) takes the lock ``<dir>/loop.lock`` (flock: one loop
  per directory; a restarted ag_ex waits here until the previous loop process has written its
  last checkpoint and exited), restores the checkpoint if there is a valid one and then holds
  position (``resume``: every arm, the torso, the head and the hands at their restored
  setpoints, frozen, so a held jar stays held where it was; safe mode stays safe mode);
- every ``CHECKPOINT_PERIOD`` cycles (1 s of simulated time) the loop encodes the state into
  a shared-memory ``LatestValue`` (``LoopCheckpoints.publish``: ≈ 15 µs once a second, see
  docs/executor.md); the communication side's ``CheckpointWriter`` thread writes it to disk
  (tmp + fsync + ``os.replace``), so the loop makes no file I/O while it runs;
- when the loop ends (``Shutdown`` at a clean stop, SIGTERM/SIGINT of the loop process, or its
  parent gone: ag_ex was killed) it writes the final checkpoint itself, after its last cycle.

Simplification (named): when the loop process itself dies without running its exit path
(SIGKILL of the loop process or of the whole process group, a power cut), the world goes back
to the last checkpoint: up to 1 s of simulated time (plus ``WRITE_PERIOD`` of wall time).
Velocities are restored with the positions. Derived quantities (contacts, actuator forces,
sensor readings) are recomputed from the restored state by ``mj_forward``, so the first cycle
after a restore sees them 1 ms later than the uninterrupted run would have.

Where (``checkpoint_dir``): ``ROCO_EX_STATE`` if set, else ``<ROCO_RUN_DIR>/ag_ex_state`` when
``ROCO_RUN_DIR`` is set (a new run folder starts fresh; a restart in the same run restores),
else nowhere (no checkpoints). ``ROCO_EX_FRESH=1`` deletes the checkpoint at start.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import logging
import math
import os
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import msgspec
import numpy as np

from velma.executor.state import SNAPSHOT_SIDES

if TYPE_CHECKING:
    import mujoco

    from shared.fipa_codec.languages.l_sd import Observation
    from velma.executor.handoff import LatestValue
    from velma.executor.loop import ControlLoop
    from velma.executor.runtime import Runtime

log = logging.getLogger(__name__)

FORMAT = "roco-ex-checkpoint/1"
FILE_NAME = "world.ckpt"
LOCK_NAME = "loop.lock"
REFUSED_SUFFIX = ".refused"  # a refused checkpoint is kept next to the new one, renamed
STATE_ENV = "ROCO_EX_STATE"
RUN_DIR_ENV = "ROCO_RUN_DIR"
FRESH_ENV = "ROCO_EX_FRESH"
STATE_IN_RUN_DIR = "ag_ex_state"
RESTART_WHY = "ag_ex restarted"  # the loop's ``holding`` after a restore
CHECKPOINT_PERIOD = 1000  # cycles (1 s of simulated time) between checkpoints
CHECKPOINT_PHASE = 7  # … in cycles 7, 1007…: no state publication (3 mod 20), no contact scan (0, 5 mod 10)
CHECKPOINT_CAPACITY = 1 << 20  # B of the shared block (the kitchen's checkpoint is ≈ 11 kB)
WRITE_PERIOD = 0.25  # s between the communication side's looks at the shared block
LOCK_TIMEOUT = 20.0  # s a starting loop waits for the previous one to write its last checkpoint
SIDES = SNAPSHOT_SIDES  # = velma.control.robot_model.SIDES
MODES = ("joint", "cart", "safe")  # ArmCommand.mode, as a number in the checkpoint


def checkpoint_dir(environ: Mapping[str, str] | None = None) -> Path | None:
    """The checkpoint directory from the environment (default ``os.environ``): ``ROCO_EX_STATE``;
    else ``<ROCO_RUN_DIR>/ag_ex_state``; else None (no checkpoints). Empty values count as unset."""
    env = os.environ if environ is None else environ
    if env.get(STATE_ENV):
        return Path(env[STATE_ENV])
    if env.get(RUN_DIR_ENV):
        return Path(env[RUN_DIR_ENV]) / STATE_IN_RUN_DIR
    return None


def fresh_start(environ: Mapping[str, str] | None = None) -> bool:
    """True when ``ROCO_EX_FRESH=1``: start from the initial scene, deleting the checkpoint."""
    env = os.environ if environ is None else environ
    return env.get(FRESH_ENV, "") == "1"


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
    physics = np.frombuffer(ckpt.physics, dtype=np.float64).copy()
    if not np.all(np.isfinite(physics)):
        raise CheckpointError("non-finite physics state")
    mujoco.mj_setState(rt.model, rt.data, physics, ckpt.state_sig)
    mujoco.mj_forward(rt.model, rt.data)
    _unpack(rt, controller)
    rt.held.update(held)
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


# ---------------------------------------------------------------------- files
def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that a reader sees the old or the new file, never a part
    (a temporary file in the same directory, fsync, ``os.replace``). Raises OSError."""
    tmp = path.with_name(f"{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


class DirLock:
    """An exclusive ``flock`` on ``<directory>/loop.lock``, held for the life of the loop
    process (the kernel releases it when the process ends, however it ends)."""

    def __init__(self, directory: Path) -> None:
        self.path = directory / LOCK_NAME
        self._fd: int | None = None

    def acquire(self, timeout: float) -> bool:
        """Take the lock, waiting up to ``timeout`` s for its holder to exit (startup only)."""
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    os.close(fd)
                    return False
                time.sleep(0.05)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return True

    def holder(self) -> str:
        """The pid written by the current holder ('?' if unreadable)."""
        try:
            return self.path.read_text().strip() or "?"
        except OSError:
            return "?"

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


class RestoreReport(msgspec.Struct, frozen=True, kw_only=True):
    """What the loop process did with the checkpoint at start, for the communication side to
    log: ``restored`` (and from which ``sim_time``, how old: ``age`` s of wall time), or why not.
    ``text`` is the log line either way, a warning when ``refused`` (a checkpoint or the
    directory was there but unusable); ``saving``: the loop keeps checkpoints in ``path``."""

    path: str
    restored: bool
    text: str
    refused: bool = False
    saving: bool = True
    sim_time: float | None = None
    age: float | None = None


class LoopCheckpoints:
    """The loop process's side (velma.executor.process.loop_main): ``open`` takes the lock and
    restores; ``publish`` puts a checkpoint into the shared block (every ``CHECKPOINT_PERIOD``
    cycles); ``close`` writes the last one to disk and releases the lock."""

    def __init__(self, directory: Path, lock: DirLock, capture: Capture, block: LatestValue | None) -> None:
        self.directory = directory
        self.path = directory / FILE_NAME
        self.lock = lock
        self.capture = capture
        self.block = block
        self.dropped: str | None = None  # why publishing stopped (a record too big for the block)

    @classmethod
    def open(
        cls, directory: Path, rt: Runtime, loop: ControlLoop[Any], *, block: str, fresh: bool
    ) -> tuple[LoopCheckpoints | None, RestoreReport]:
        """Take the directory's lock (waiting ``LOCK_TIMEOUT`` s for a previous loop), then
        restore its checkpoint into ``rt``/``loop`` and ``resume``, unless ``fresh`` (delete
        it) or it is missing or refused. Returns None and a report when the directory cannot
        be used (checkpoints off for this run of the loop)."""
        from velma.executor.handoff import LatestValue

        path = directory / FILE_NAME
        try:
            directory.mkdir(parents=True, exist_ok=True)
            lock = DirLock(directory)
            if not lock.acquire(LOCK_TIMEOUT):
                text = (
                    f"checkpoint directory {directory} is in use by another loop (pid {lock.holder()}): "
                    "initial scene, no checkpoints"
                )
                return None, RestoreReport(
                    path=str(path), restored=False, refused=True, saving=False, text=text
                )
        except OSError as exc:
            text = f"checkpoint directory {directory} unusable ({exc}): initial scene, no checkpoints"
            return None, RestoreReport(path=str(path), restored=False, refused=True, saving=False, text=text)
        capture = Capture(rt)
        report = cls._restore(path, rt, loop, capture.fp, fresh=fresh)
        shared = LatestValue.attach(block, CHECKPOINT_CAPACITY) if block else None
        keeper = cls(directory, lock, capture, shared)
        keeper.publish(loop.holding)
        return keeper, report

    @staticmethod
    def _restore(
        path: Path, rt: Runtime, loop: ControlLoop[Any], fp: Fingerprint, *, fresh: bool
    ) -> RestoreReport:
        if fresh:
            existed = path.exists()
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            what = f"checkpoint {path} deleted" if existed else f"no checkpoint at {path}"
            return RestoreReport(path=str(path), restored=False, text=f"{FRESH_ENV}=1: {what}, initial scene")
        try:
            raw = path.read_bytes()
        except FileNotFoundError:
            text = f"no checkpoint at {path}: initial scene"
            return RestoreReport(path=str(path), restored=False, text=text)
        except OSError as exc:
            text = f"checkpoint {path} not readable ({exc}): initial scene"
            return RestoreReport(path=str(path), restored=False, refused=True, text=text)
        try:
            ckpt = decode(raw, fp)
            apply(rt, ckpt)
        except CheckpointError as exc:
            kept = path.with_name(path.name + REFUSED_SUFFIX)
            with contextlib.suppress(OSError):
                os.replace(path, kept)
            text = f"refused checkpoint {path} (kept as {kept.name}): {exc}; initial scene"
            return RestoreReport(path=str(path), restored=False, refused=True, text=text)
        resume(loop, ckpt)
        age = max(0.0, time.time() - ckpt.wall_time)
        held = ", ".join(f"{s} hand holds {b}" for s, b in ckpt.held.items() if b is not None)
        text = (
            f"restored world from checkpoint {path} (sim time {ckpt.sim_time:.3f} s, age {age:.1f} s"
            f"{'; ' + held if held else ''})"
        )
        return RestoreReport(path=str(path), restored=True, text=text, sim_time=ckpt.sim_time, age=age)

    def publish(self, holding: str | None) -> None:
        """Encode the world now into the shared block (called from the loop: no I/O)."""
        if self.block is None:
            return
        record = self.capture.take(holding)
        if len(record) > self.block.capacity - 4:
            self.dropped = f"checkpoint of {len(record)} B does not fit {self.block.capacity} B"
            self.block = None
            return
        self.block.write(record)

    def close(self, holding: str | None) -> str | None:
        """Write the final checkpoint to disk (after the loop's last cycle), release the
        shared block and the lock; returns an error text instead of raising."""
        error = self.dropped
        try:
            write_atomic(self.path, self.capture.take(holding))
        except OSError as exc:
            error = f"final checkpoint not written to {self.path}: {exc}"
        if self.block is not None:
            self.block.close()
            self.block = None
        self.lock.release()
        return error


class CheckpointWriter:
    """The communication side's writer (ExecutorProcess): every ``period`` s of wall time,
    if the loop published a new checkpoint into ``block``, write it to ``path`` atomically.
    Runs in its own thread, so the loop process makes no file I/O while it runs."""

    def __init__(self, block: LatestValue, path: Path, period: float = WRITE_PERIOD) -> None:
        self.block = block
        self.path = path
        self.period = period
        self.writes = 0
        self._seen = 0
        self._failing = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="velma-checkpoint", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop writing (before the loop writes its final checkpoint itself)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            self.flush()

    def flush(self) -> None:
        """Write the block's checkpoint if it is newer than the last one written."""
        version = self.block.version
        if version == self._seen:
            return
        raw = self.block.read()
        if raw is None:
            return
        try:
            write_atomic(self.path, raw)
        except OSError as exc:
            if not self._failing:
                log.warning("checkpoint not written to %s: %s", self.path, exc)
            self._failing = True
            return
        if self._failing:
            log.info("checkpoints written to %s again", self.path)
        self._failing = False
        self._seen = version
        self.writes += 1


def observe_checkpoint(path: Path, *, seed: int = 0, pose_seed: int | None = None) -> Observation:
    """The ground truth of the world kept in the checkpoint file ``path``: every known
    object's pose (world frame, m) and containers' particle counts (``GroundTruth.observe``,
    velma/executor/ground_truth.py; for judging a run, never for the agents),
    for the scene of ``seed`` and ``pose_seed`` (those ag_ex ran with). Used after a run to
    judge the final world (services/scenario/chaos.py). Raises OSError when the file cannot
    be read and CheckpointError when it does not fit that scene."""
    import mujoco

    from velma.executor.runtime import Runtime as _Runtime

    rt = _Runtime(seed=seed, pose_seed=pose_seed)
    ckpt = decode(path.read_bytes(), fingerprint(rt.model))
    physics = np.frombuffer(ckpt.physics, dtype=np.float64).copy()
    mujoco.mj_setState(rt.model, rt.data, physics, ckpt.state_sig)
    mujoco.mj_forward(rt.model, rt.data)
    return rt.ground_truth.observe(rt.data)


def observe_scene(values: bytes, *, seed: int = 0, pose_seed: int | None = None) -> Observation:
    """The ground truth of a kitchen saved as raw float64 (the time, then MuJoCo's ``qpos``: a
    world process's final scene, velma/world/main.py ``FINAL_FILE``) for the scene of ``seed``
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
