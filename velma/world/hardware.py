"""Velma's hardware side in the simulated kitchen: the MuJoCo physics, the sensors a
controller reads (joint encoders, wrist force/torque sensors, the hands' tactile summary),
the inputs it writes (arm and torso torques), the servos that run on the robot itself (the
BarrettHands' finger and spread servos, the head's pan and tilt), and the safety layer that
holds the robot when its controller stops commanding it.

One ``SimulatedVelma`` is stepped by one thread: ``measure`` (the state of this cycle),
``apply`` (the command, or None: no fresh command), ``step`` (1 ms). What crosses to the
controller is the vectors of velma/world/layout.py. The three run in C++ (the ``Plant`` of
velma/control/_plant.hpp: no Python object per value) where it can run and ``ROCO_PLANT``
does not say ``python`` (velma/control/mujoco_side.py); the Python code here stays the
reference (tests/velma/test_world.py runs both side by side and compares them bit for bit).
The rare parts stay in Python either way: a new hand operation, a disturbance, the hold.

Safety hold (as a KUKA LWR4+ brakes when FRI commands stop): the arm and torso joints are held
at the pose measured when the hold began, by a stiff joint impedance on top of the physics'
own gravity and Coriolis torques (``BRAKE_STIFFNESS``, critically damped on each joint's
inertia); the hands' and the head's servos keep their targets, so a grasped object stays
grasped. The next command ends the hold.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from velma.control.hand import ContactMonitor, Hands
from velma.control.joints import HEAD_JOINTS, SIDES, TORSO_JOINT, JointMap, arm_joints, robot_joints
from velma.control.mujoco_side import bind_servos, make_plant, mujoco_side_unavailable, plant_choice
from velma.model.scene import N_PARTICLES, initial_state, load_kitchen
from velma.world.layout import (
    COMMAND,
    HAND_KEEP,
    HAND_OP,
    MEASURED,
    SELF_SLOTS,
    TOUCH_SLOTS,
)

DT = 0.001
"""The physics step and the link's cycle (s): 1 kHz (velma/model/README.md "Control")."""
HEAD_RATE = 1.04
"""The head servos' speed limit (rad/s; velma/model/README.md "Structure")."""
BRAKE_STIFFNESS = 2000.0
"""Joint stiffness of the safety hold (N·m/rad), ten times Velma's arm joint impedance: the
arm sags by less than a milliradian under its own weight."""
BRAKE_DAMPING_RATIO = 1.0
CONTACT_PERIOD = 10
"""Cycles between two tactile scans of a hand (10 ms); ``touch`` keeps the last one."""

Array = npt.NDArray[np.float64]
log = logging.getLogger(__name__)
_MEASURED_ORDER = (
    "time",
    "q",
    "v",
    "ft",
    "touch",
    "holding",
    "hand",
    "hand_seq",
    "self_touch",
    "head",
    "disturb_seq",
)
"""The ``MEASURED`` fields whose offsets the C++ world cycle takes, in its order (_plant.hpp)."""


class SimulatedVelma:
    """The kitchen with Velma in it, seen from the controller's side as hardware.

    ``seed`` jitters the jar's content, ``pose_seed`` randomises the jar's and the bowl's
    poses (velma/model/scene.py; None: those of kitchen.xml), ``removed`` takes that many
    spheres out of the jar before the start (scene.py ``remove_content``). ``compiled``: step in C++
    (module docstring): True (required), False (Python), None (as ``ROCO_PLANT`` says; unset:
    C++ where it can run). Raises KeyError when the model lacks one of Velma's joints,
    actuators or sensors, ValueError when the robot has another number of joints than the link
    carries or ``ROCO_PLANT`` another value, RuntimeError when C++ is required and cannot run."""

    def __init__(
        self,
        *,
        seed: int = 0,
        n_particles: int | None = None,
        pose_seed: int | None = None,
        compiled: bool | None = None,
        removed: int = 0,
    ) -> None:
        model = load_kitchen(N_PARTICLES if n_particles is None else n_particles, seed, pose_seed)
        model.opt.timestep = DT
        self.model = model
        self.data = initial_state(model, removed=removed)
        # Pinocchio's order without Pinocchio; ValueError: not the link's N_JOINTS (velma/control/joints.py)
        self.jmap = JointMap.build(model, robot_joints(model))
        held = [j for s in SIDES for j in arm_joints(s)] + [TORSO_JOINT]
        motors = [f"{s}_arm_{k}_motor" for s in SIDES for k in range(7)] + ["torso_0_motor"]
        self.tau_act = np.array([self.jmap.ctrl[m] for m in motors])
        self.tau_q = np.array([model.joint(j).qposadr[0] for j in held])
        self.tau_v = np.array([model.joint(j).dofadr[0] for j in held])
        self.head_act = np.array([self.jmap.ctrl["head_pan_servo"], self.jmap.ctrl["head_tilt_servo"]])
        self.head_q = np.array([model.joint(j).qposadr[0] for j in HEAD_JOINTS])
        self._head_servos = np.tile(self.data.qpos[self.head_q], 2)
        self.head_set = self._head_servos[:2]
        """The head servos' setpoints (rad: pan, tilt; a view), ramping to ``head_target``."""
        self.head_target = self._head_servos[2:]
        """The head servos' targets (rad: pan, tilt; a view)."""
        self.hands = Hands(model)
        self.hands.reset_from(self.data)
        self._seqs = np.zeros(len(SIDES) + 1)
        self.hand_seq = self._seqs[: len(SIDES)]
        """Per side the sequence number of the last hand command taken (0: none yet; a view)."""
        self.contacts = ContactMonitor(model)
        self.ft_adr = [
            (int(model.sensor(f"{s}_ft_force").adr[0]), int(model.sensor(f"{s}_ft_torque").adr[0]))
            for s in SIDES
        ]
        self.cycles = 0
        """Steps taken since this world was made."""
        self.hold_q: Array | None = None
        self._brake_damping = np.zeros(len(self.tau_v))
        """The joint positions the safety layer holds (the ``tau`` joints' order), or None."""
        self._q, self._v = MEASURED.slice("q"), MEASURED.slice("v")
        self._ft, self._touch = MEASURED.fields["ft"][0], MEASURED.fields["touch"][0]
        self._time, self._holding = MEASURED.fields["time"][0], MEASURED.fields["holding"][0]
        self._tau, self._hand, self._head = COMMAND.slice("tau"), COMMAND.slice("hand"), COMMAND.slice("head")
        self._hand_state, self._hand_seq = MEASURED.slice("hand"), MEASURED.slice("hand_seq")
        self._self_touch, self._head_set = MEASURED.slice("self_touch"), MEASURED.slice("head")
        self._disturb, self._disturb_seq = COMMAND.slice("disturb"), MEASURED.fields["disturb_seq"][0]
        # per cycle: MjData's arrays taken once (each attribute read makes a new numpy view),
        # the force/torque sensors' addresses as one index array
        self._qpos, self._qvel, self._ctrl = self.data.qpos, self.data.qvel, self.data.ctrl
        self._sensordata = self.data.sensordata
        self._ft_adr = np.array([a + i for pair in self.ft_adr for a in pair for i in range(3)])
        self._ft_out = slice(self._ft, self._ft + len(self._ft_adr))
        self._head_rate = HEAD_RATE * DT
        self._ctrl[self.head_act] = self.head_set  # a step writes it again only while it moves
        self.plant = self._compiled(compiled)
        """The C++ side of the cycle (module docstring), or None: Python."""

    def _compiled(self, wanted: bool | None) -> Any:
        if wanted is None:
            wanted = plant_choice()
        why = mujoco_side_unavailable() if wanted is not False else "not requested"
        if why is not None:
            if wanted:
                raise RuntimeError(f"no compiled world cycle: {why}")
            if wanted is None:
                log.warning("the world's cycle runs in Python: %s", why)
            return None
        model, motors = self.model, self.tau_act.tolist()
        plant = make_plant(model, self.data, self.jmap, self.contacts, motors[:-1], motors[-1])
        head_act = (int(self.head_act[0]), int(self.head_act[1]))
        bind_servos(plant, self.hands, self._head_servos, head_act, dt=DT, head_step=self._head_rate)
        plant.bind_world(
            [MEASURED.fields[n][0] for n in _MEASURED_ORDER] + [TOUCH_SLOTS, SELF_SLOTS, CONTACT_PERIOD],
            [COMMAND.fields[n][0] for n in ("tau", "hand", "head", "disturb")] + [HAND_OP],
            motors,
            [a for pair in self.ft_adr for a in pair],
            self._seqs,
        )
        return plant

    @property
    def disturb_seq(self) -> float:
        """The sequence number of the last disturbance taken (0: none yet)."""
        return float(self._seqs[-1])

    @property
    def time(self) -> float:
        """The simulated time (s)."""
        return float(self.data.time)

    @property
    def holding(self) -> bool:
        """True while the safety layer holds the robot."""
        return self.hold_q is not None

    @property
    def scene_size(self) -> int:
        """Values of ``scene``: the time and MuJoCo's ``qpos``."""
        return 1 + int(self.model.nq)

    def scene(self, out: Array) -> None:
        """Write the whole kitchen now into ``out`` (``scene_size`` float64: time, ``qpos``)."""
        out[0] = self.data.time
        out[1:] = self.data.qpos

    def measure(self, out: Array) -> None:
        """Write this cycle's measured state into ``out`` (``MEASURED.size`` float64; ``touch``
        is rewritten per hand and ``self_touch`` once every ``CONTACT_PERIOD`` cycles: keep
        ``out`` between calls)."""
        if self.plant is not None:
            self.plant.measure(out, self.cycles, self.hold_q is not None)
            return
        data = self.data
        out[self._time] = data.time
        np.take(self._qpos, self.jmap.qpos_adr, out=out[self._q])
        np.take(self._qvel, self.jmap.dof_adr, out=out[self._v])
        np.take(self._sensordata, self._ft_adr, out=out[self._ft_out])
        phase = self.cycles % CONTACT_PERIOD
        for k, side in enumerate(SIDES):
            if phase != k * CONTACT_PERIOD // 2:
                continue  # each hand's scan once a period, the two half a period apart
            at = self._touch + 2 * TOUCH_SLOTS * k
            touched = sorted(self.contacts.touching(data, side).items(), key=lambda bg: -bg[1])[:TOUCH_SLOTS]
            slots = out[at : at + 2 * TOUCH_SLOTS]
            slots[0::2], slots[1::2] = -1.0, 0.0
            for i, (body, geoms) in enumerate(touched):
                slots[2 * i], slots[2 * i + 1] = body, geoms
        if phase == CONTACT_PERIOD // 4:  # between the two hands' scans
            pairs = self.contacts.self_contacts(data)[:SELF_SLOTS]
            slots = out[self._self_touch]
            slots[:] = -1.0
            for i, (a, b) in enumerate(pairs):
                slots[2 * i], slots[2 * i + 1] = a, b
        out[self._holding] = 1.0 if self.holding else 0.0
        out[self._hand_state] = self.hands.state.ravel()
        out[self._hand_seq] = self.hand_seq
        out[self._head_set] = self.head_set
        out[self._disturb_seq] = self.disturb_seq

    def apply(self, command: Array | None) -> None:
        """The controller's ``command`` (``COMMAND.size`` float64) for the next step, or None:
        no fresh one came, and the safety layer holds the robot (module docstring)."""
        data = self.data
        if command is None:
            if self.hold_q is None:
                self.hold_q = data.qpos[self.tau_q].copy()
                full = np.zeros((self.model.nv, self.model.nv))
                mujoco.mj_fullM(self.model, data, full)
                inertia = full[self.tau_v, self.tau_v]  # each held joint's, as the hold begins
                self._brake_damping = 2.0 * BRAKE_DAMPING_RATIO * np.sqrt(BRAKE_STIFFNESS * inertia)
            self._brake()
            return
        self.hold_q = None
        if self.plant is not None:
            fresh = self.plant.apply(command)  # the torques and the head's targets
            if fresh:
                self._take(command, fresh)
            return
        self._ctrl[self.tau_act] = command[self._tau]
        self.head_target[:] = command[self._head]
        self._take(command, 0b111)

    def _take(self, command: Array, which: int) -> None:
        """Take the hand operations (bit k: side k) and the disturbance (bit 2) of ``command``
        that ``which`` names and that are new (their sequence numbers changed)."""
        hand = command[self._hand]
        for k, side in enumerate(SIDES):
            if not which & (1 << k) or hand[HAND_OP * k] == self.hand_seq[k]:
                continue  # taken already: the command repeats every cycle
            seq, op, proximal, spread = hand[HAND_OP * k : HAND_OP * (k + 1)].tolist()
            self.hand_seq[k] = seq
            if op == HAND_KEEP:
                self.hands.keep(side)
            else:
                self.hands.command(side, proximal, None if math.isnan(spread) else spread)
        if which & 0b100 and command[self._disturb.start] != self._seqs[-1]:
            seq, body, dx, dy, dz, tilt = command[self._disturb].tolist()
            self._seqs[-1] = seq
            # a body that is not free cannot be moved: the command's sender checks (``displace``)
            if 0 <= body < self.model.nbody and is_free(self.model, int(body)):
                displace(self.model, self.data, int(body), (dx, dy, dz), tilt)

    def _brake(self) -> None:
        data = self.data
        q, v = data.qpos[self.tau_q], data.qvel[self.tau_v]
        assert self.hold_q is not None
        tau = data.qfrc_bias[self.tau_v] + BRAKE_STIFFNESS * (self.hold_q - q) - self._brake_damping * v
        data.ctrl[self.tau_act] = tau

    def step(self) -> None:
        """One physics step of ``DT``, the hands' and the head's servos first."""
        if self.plant is not None:
            self.plant.step_world()
            self.cycles += 1
            return
        data = self.data
        self.hands.step(data, DT)
        target, now = self.head_target, self.head_set
        if target[0] != now[0] or target[1] != now[1]:  # at rest most of the time
            ramp(now, target, self._head_rate)
            self._ctrl[self.head_act] = now
        mujoco.mj_step(self.model, data)
        self.cycles += 1


def ramp(now: Array, target: Array, step: float) -> None:
    """Move each servo setpoint of ``now`` (rad, shape (n,), in place) by at most ``step``
    (rad) towards ``target`` (same shape): one cycle of the head's pan and tilt servos, whose
    ``step`` is ``HEAD_RATE · DT`` (the neck's speed limit; velma/model/README.md)."""
    for i in range(len(now)):
        now[i] += min(max(float(target[i] - now[i]), -step), step)


def is_free(model: mujoco.MjModel, body: int) -> bool:
    """True when body id ``body`` moves on a free joint (an object a person can move)."""
    j = int(model.body_jntadr[body])
    return j >= 0 and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE


def displace(
    model: mujoco.MjModel, data: mujoco.MjData, body: int, delta: tuple[float, float, float], tilt: float
) -> None:
    """Move free body id ``body`` by ``delta`` (world, m), turn it by ``tilt`` (rad) about the
    world's x axis through its origin, and stop it: a disturbance of the kitchen (a person moves
    or knocks over an object), not a robot action. What it carries (its content, the bodies
    named ``<body>_content*``, on slide joints) moves and turns with it. The caller checks that
    ``body`` is free (``is_free``)."""
    mujoco.mj_kinematics(model, data)  # body positions of the current qpos
    origin = data.xpos[body].copy()
    shift = np.asarray(delta, dtype=float)
    c, s = math.cos(tilt), math.sin(tilt)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    j = int(model.body_jntadr[body])
    qa, va = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
    data.qpos[qa : qa + 3] += shift
    turned = np.empty(4)
    half = np.array([math.cos(tilt / 2), math.sin(tilt / 2), 0.0, 0.0])
    mujoco.mju_mulQuat(turned, half, data.qpos[qa + 3 : qa + 7])
    data.qpos[qa + 3 : qa + 7] = turned
    data.qvel[va : va + 6] = 0.0
    prefix = f"{model.body(body).name}_content"
    for other in range(model.nbody):
        if other != body and model.body(other).name.startswith(prefix):
            at = data.xpos[other]
            step = origin + turn @ (at - origin) + shift - at
            first, count = int(model.body_jntadr[other]), int(model.body_jntnum[other])
            for k in range(first, first + count):  # the content's slide joints (world axes)
                if model.jnt_type[k] == mujoco.mjtJoint.mjJNT_SLIDE:
                    data.qpos[model.jnt_qposadr[k]] += float(model.jnt_axis[k] @ step)
                    data.qvel[model.jnt_dofadr[k]] = 0.0
    mujoco.mj_forward(model, data)
