"""The single-threaded robot runtime: the MuJoCo kitchen, the controllers and the per-cycle
step (read state → controllers → actuators → physics step). ``Executor`` runs it in its loop
thread; tests may drive it directly.

Cycle (1 kHz, physics dt = 1 ms, paper §5.3 / velma/model/README.md "Control"):
1. the running primitive updates the setpoints;
2. the hands and the head get their position-servo controls, and the impedance law
   (``make_controller``: compiled, velma/control/compiled.py, or the Python reference
   ``VelmaController``) computes arm and torso torques (Pinocchio, from MuJoCo's state mapped
   by joint name);
3. ``mujoco.mj_step``.

With the compiled plant (velma/executor/plant.py) steps 2–3 run in C++, the servo steps
included; the Python ``Hands.step`` and ``_step_head`` stay their reference.

Attached to a world process (``link``: velma/world/, velma/executor/world_link.py) the runtime
is the controller only: step 2 computes the torques from the world's measured state and sends
them with the servos' targets, and step 3 waits for the world's next state instead of stepping
physics; ``data`` is then a mirror of the world's kitchen, never stepped here.

Cartesian setpoints are kept in the world frame; when the torso turns (MoveJoints), the
setpoints of arms in Cartesian mode are carried with it (they are re-expressed each cycle
from their pose relative to torso_link0 at the start of the motion).
"""

from __future__ import annotations

import logging
import math
import time
from typing import cast

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from velma.control.compiled import CompiledController, make_controller
from velma.control.hand import ContactMonitor, Hands
from velma.control.ik import DlsKernel
from velma.control.joints import HEAD_JOINTS, SIDES, TORSO_JOINT, Array, JointMap, arm_joints
from velma.control.mujoco_side import plant_choice
from velma.control.robot_model import RobotModel
from velma.control.self_collision import SelfCollision
from velma.executor.capture import DEFAULT_PERCEPTION
from velma.executor.ground_truth import GroundTruth
from velma.executor.payloads import HeldLoads
from velma.executor.plant import CompiledPlant, plant_unavailable
from velma.executor.state import LINK_BODIES
from velma.executor.world_link import WorldLink
from velma.model import grip_frame
from velma.model.scene import N_PARTICLES, initial_state, load_kitchen
from velma.world.hardware import (  # the robot's rates, stated once
    CONTACT_PERIOD,
    DT,
    HEAD_RATE,
    displace,
    is_free,
    ramp,
)
from velma.world.link import RobotLink
from velma.world.timing import HOLD_CYCLES

log = logging.getLogger(__name__)

TORSO_Z = 0.03  # m, TORSO_JOINT above torso_base
AWAY_GAP_S = (HOLD_CYCLES + 1) * DT
"""A gap (s) between two consecutive states wider than this was time the world held the robot
without its controller (``Runtime.away_s``)."""


def torso_frame(angle: float) -> pin.SE3:
    """World pose of torso_link0 at torso angle ``angle`` (rad)."""
    c, s = math.cos(angle), math.sin(angle)
    return pin.SE3(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([0.0, 0.0, TORSO_Z]))


class Runtime:
    """Simulation plus controllers. Not thread-safe: one thread calls ``cycle``."""

    def __init__(
        self,
        *,
        seed: int = 0,
        n_particles: int | None = None,
        pose_seed: int | None = None,
        compiled_plant: bool | None = None,
        link: RobotLink | None = None,
        link_spin_s: float = 0.0,
    ) -> None:
        """``seed`` jitters the jar content, ``pose_seed`` randomises the jar and bowl poses
        (velma/model/scene.py; None: the poses of kitchen.xml). ``compiled_plant``: run the
        cycle's MuJoCo side in C++ (velma/executor/plant.py): True, or False for the Python
        cycle; None: as ``ROCO_PLANT`` says (velma/control/mujoco_side.py ``plant_choice``), unset
        the compiled plant where it can run, else the Python cycle with a warning. Raises
        RuntimeError when the compiled plant is required and cannot run, ValueError for another
        value of ``ROCO_PLANT``.

        ``link``: the robot link of a world process to attach to (module docstring); the
        runtime then starts from the robot and the kitchen as the world has them, holding what
        a hand grasps (``WorldLink.grasped``), and runs no plant. ``link_spin_s``: how long a
        cycle spins before it sleeps while it waits for the world. Raises RuntimeError when
        the world publishes nothing (``ATTACH_TIMEOUT_S``), ValueError when its kitchen is
        another model than this one's, or orders the robot's joints otherwise than Pinocchio
        (velma/executor/world_link.py ``WorldLink``)."""
        self.pose_seed = pose_seed
        self.model = load_kitchen(N_PARTICLES if n_particles is None else n_particles, seed, pose_seed)
        self.model.opt.timestep = DT
        self._data = initial_state(self.model)
        self.robot = RobotModel()
        self.ik_data = self.robot.model.createData()  # the IK search's own (see primitives)
        self.self_collision = SelfCollision(self.robot)
        """The IK's self-collision check (velma/control/self_collision.py)."""
        self.joint_v_index = tuple(self.robot.v_index(n) for n in self.robot.joint_names)
        self.snapshot_index = np.array(self.joint_v_index, dtype=np.intp)
        """``joint_v_index`` as an index array (velma.executor.gather.raw_state)."""
        self.grip_site = {s: self.model.site(grip_frame(s)).id for s in SIDES}
        # the snapshot's link bodies and wrist F/T sensors (velma.executor.state)
        self.link_ids = np.array([self.model.body(n).id for n in LINK_BODIES], dtype=np.intp)
        self.ft_adr = {
            s: (
                int(self.model.sensor(f"{s}_ft_force").adr[0]),
                int(self.model.sensor(f"{s}_ft_torque").adr[0]),
            )
            for s in SIDES
        }
        self.ft_site = {s: self.model.site(f"{s}_ft_sensor").id for s in SIDES}
        """The site of each wrist F/T sensor: its frame is the sensor's (``ft_force``)."""
        self.jmap = JointMap.build(self.model, self.robot.joint_names)
        self.ctrl = make_controller(self.robot, DT)
        self.ik_kernel: DlsKernel | None = (
            self.ctrl.ik_kernel if isinstance(self.ctrl, CompiledController) else None
        )
        """The IK's iteration in C++ with the compiled law (velma/control/ik.py ``DlsKernel``),
        else None: the Python iteration."""
        self.world: WorldLink | None = None
        """The attached world process (``link``), or None: the physics runs here."""
        if link is not None:
            self.world = WorldLink(link, self.model, self._data, self.jmap, spin_s=link_spin_s)
            compiled_plant = False
        self.hands: Hands = self.world.hands if self.world is not None else Hands(self.model)
        self.contacts = ContactMonitor(self.model)
        self.ground_truth = GroundTruth(self.model)
        """The physics' truth (velma/executor/ground_truth.py): the agents' Observation only
        when ``observe_by_camera`` is False (``ROCO_PERCEPTION=truth``)."""
        self.observe_by_camera = DEFAULT_PERCEPTION == "camera"
        """An Observe ends with a ``WorldCapture`` for the camera (velma/executor/capture.py),
        else with the ground truth; the host sets it from ``ROCO_PERCEPTION``."""
        self.arm_act = {s: np.array([self.jmap.ctrl[f"{s}_arm_{k}_motor"] for k in range(7)]) for s in SIDES}
        self.torso_act = self.jmap.ctrl["torso_0_motor"]
        self.head_act = (self.jmap.ctrl["head_pan_servo"], self.jmap.ctrl["head_tilt_servo"])
        self.head_qadr = np.array([self.model.joint(j).qposadr[0] for j in HEAD_JOINTS])
        self.head_range = self.model.jnt_range[[self.model.joint(j).id for j in HEAD_JOINTS]].copy()
        """Pan and tilt limits (rad, shape (2, 2): lower, upper per joint)."""
        self.head_pan_body = self.model.body("head_pan_link").id
        self.torso_qadr = int(self.model.joint(TORSO_JOINT).qposadr[0])
        self.head = np.concatenate([self.data.qpos[self.head_qadr]] * 2)
        """The head's servo setpoints, then their targets (rad, (4,): pan, tilt, pan, tilt):
        the storage of ``head_set`` and ``head_target`` (and of the compiled plant's servo step)."""
        self.gaze: Array | None = None
        """The world point (m) the head keeps looking at while the torso turns (set by LookAt;
        a MoveJoints of the head joints ends it); None: the head holds its joint angles. Not
        in a checkpoint: after a restore the head holds its angles until the next LookAt."""
        self.tilt_about: dict[str, tuple[Array, Array] | None] = {s: None for s in SIDES}
        """Per arm, the unit axis (3,) and the pivot (3,, m; world) of the Tilt that last
        turned what it holds, until a MoveTool of that arm or a MoveJoints of it or of the
        torso: a halt turns a tilted held object upright about them
        (velma/executor/halt.py ``HaltPrimitive``). Not in a checkpoint."""
        self.upright_posture: dict[str, Array | None] = {s: None for s in SIDES}
        """Per arm, the null-space posture (7,, rad: the measured joints) it had when a Tilt
        began to lean what it holds from upright; read only while ``tilt_about`` is set (a
        Tilt from a leant start keeps it). A halt's turn upright brings the posture back to
        it, so that the arm ends as it stood before the tilt, not on the elbow of the tilted
        pose. None: unknown. Not in a checkpoint."""
        self.held: dict[str, int | None] = {s: None for s in SIDES}
        self.loads = HeldLoads(self.model, self.ctrl, self.ft_site)
        """The load data of what the hands hold, given to the law (velma/executor/payloads.py)."""
        self.touch: dict[str, dict[int, int]] = {s: {} for s in SIDES}
        self.lost_cycles: dict[str, int] = {s: 0 for s in SIDES}
        self.cycles = 0
        self.plant: CompiledPlant | None = None
        """The compiled MuJoCo side of the cycle (velma/executor/plant.py), or None: the
        Python cycle."""
        if compiled_plant is None:
            compiled_plant = plant_choice()
        why = plant_unavailable(self.ctrl) if compiled_plant is not False else "not requested"
        if why is None:
            self.plant = CompiledPlant(
                self.model,
                self._data,
                cast(CompiledController, self.ctrl),
                self.jmap,
                self.contacts,
                arm_act=self.arm_act,
                torso_act=self.torso_act,
                state_index=self.snapshot_index,
                grip_site=self.grip_site,
                link_ids=self.link_ids,
                ft_adr=self.ft_adr,
            )
            self.plant.bind_servos(self.hands, self.head, self.head_act, dt=DT, head_step=HEAD_RATE * DT)
        elif compiled_plant:
            raise RuntimeError(f"no compiled plant: {why}")
        elif compiled_plant is None and isinstance(self.ctrl, CompiledController):
            log.warning("the cycle's MuJoCo side runs in Python: %s (velma/executor/plant.py)", why)
        self.waited_s = 0.0
        """Attached to a world process: how long (s) the last cycle waited for its state."""
        self.away_s = 0.0
        """Attached to a world process: the world time (s) that passed while this controller
        commanded nothing and the world's safety layer held the robot (a pause of this
        process, say); ``motion_time`` leaves it out."""
        self._sensed_at = self.time
        self.part_s = np.zeros(3)
        """The last cycle's measured parts (s): primitive (set by the loop), control, physics
        (velma.executor.timing.PARTS)."""
        self._scan_phase = {0: SIDES[0], CONTACT_PERIOD // 2: SIDES[1]}
        self._self_phase = CONTACT_PERIOD // 4
        self.self_contacts = 0
        """Scans (every ``CONTACT_PERIOD`` cycles) that found the robot touching itself."""
        self.self_contact_pairs: dict[tuple[str, str], int] = {}
        """Those contacts by the geoms' (or bodies') names: how many scans saw each pair."""
        q = self.q()
        for s in SIDES:
            self.ctrl.arm[s].q = q[self.ctrl.arm_slice[s]].copy()
        self.ctrl.torso_q = float(q[self.ctrl.torso_idx])
        if self.world is None:
            self.hands.reset_from(self.data)
        else:
            self.head[:] = np.concatenate([self.world.head_set] * 2)
            self.held = {s: self.world.grasped(s) for s in SIDES}
            self.touch = {s: self.world.touching(s) for s in SIDES}
        self.ctrl.kinematics(q, self.v())
        for s in SIDES:
            self.ctrl.state[s].grip = self.ctrl.grip_pose(s)

    # ------------------------------------------------------------------ state
    @property
    def plant_name(self) -> str:
        """Where the cycle's MuJoCo side runs: ``world process`` (attached to one: the loop steps
        no physics), ``compiled`` (``plant``) or ``python``."""
        if self.world is not None:
            return "world process"
        return "python" if self.plant is None else "compiled"

    @property
    def head_set(self) -> Array:
        """The head's servo setpoints now (pan, tilt; rad, (2,), a view of ``head``);
        assigning writes them."""
        out: Array = self.head[:2]
        return out

    @head_set.setter
    def head_set(self, value: npt.ArrayLike) -> None:
        self.head[:2] = value

    @property
    def head_target(self) -> Array:
        """Where the head's setpoints go, ≤ HEAD_RATE (pan, tilt; rad, (2,), a view of
        ``head``); assigning writes them."""
        out: Array = self.head[2:]
        return out

    @head_target.setter
    def head_target(self, value: npt.ArrayLike) -> None:
        self.head[2:] = value

    @property
    def data(self) -> mujoco.MjData:
        """MuJoCo's data of the kitchen: stepped here, or, attached to a world process, its
        mirror, brought up to the world's latest state when read (``WorldLink.mirror``)."""
        if self.world is not None and self.world.stale:
            self.world.mirror()
        return self._data

    @property
    def time(self) -> float:
        """Simulation time (s)."""
        return self.world.time if self.world is not None else float(self._data.time)

    @property
    def motion_time(self) -> float:
        """The primitives' clock (s): ``time`` less ``away_s``. A motion whose controller
        stopped (the world held the robot where it was) goes on along its path from where it
        stopped, as a trajectory generator on the controller's own clock does, instead of its
        setpoint leaping ahead by the time away."""
        return self.time - self.away_s

    def q(self) -> Array:
        """Pinocchio q (33,) rad, measured."""
        if self.world is not None:
            return self.world.q.copy()
        return self.jmap.q(self._data)

    def v(self) -> Array:
        """Pinocchio v (33,) rad/s, measured."""
        if self.world is not None:
            return self.world.v.copy()
        return self.jmap.v(self._data)

    def arm_q(self, side: str) -> Array:
        """Measured arm joint positions (7,) rad."""
        out: Array = self.q()[self.ctrl.arm_slice[side]].copy()
        return out

    def grip(self, side: str) -> pin.SE3:
        """Measured grip-frame pose (world) as of the last control update."""
        return self.ctrl.state[side].grip

    def ft_force(self, side: str) -> Array:
        """The force (N, (3,), world axes) that ``side``'s arm exerts on its hand through the
        wrist F/T sensor: MuJoCo's ``{side}_ft_force`` (the interaction between arm_7_link and
        the palm's subtree: palm, fingers and what they hold; velma/model/robot_mjcf.py) turned
        from the sensor frame ``{side}_ft_sensor`` into the world's. At rest it carries the
        hand's and the held object's weight (+z); a surface pushing the hand or what it holds
        up lowers it. As of the last physics step, with either cycle: the compiled plant steps
        the same ``mjData`` (velma/executor/plant.py)."""
        fa = self.ft_adr[side][0]
        out: Array = self.data.site_xmat[self.ft_site[side]].reshape(3, 3) @ self.data.sensordata[fa : fa + 3]
        return out

    def joint_index(self, name: str) -> int:
        """Pinocchio v index of a Velma joint; raises KeyError for an unknown name."""
        if name not in self.robot.joint_names:
            raise KeyError(name)
        return self.robot.v_index(name)

    def hold_lost(self, side: str) -> bool:
        """True when the held object of ``side`` has touched no hand geom for ≥ 100 ms."""
        return self.held[side] is not None and self.lost_cycles[side] * CONTACT_PERIOD >= 100

    # ------------------------------------------------------------------ cycle
    def cycle(self) -> None:
        """One 1 ms control cycle after the setpoints were updated (see module docstring);
        the control and physics parts of its time go to ``part_s``; attached to a world, the
        time spent waiting for its next state goes to ``waited_s``, not to a part."""
        t0 = time.perf_counter()
        data = self._data
        part = self.part_s
        if self.world is not None:
            world = self.world
            taus, tau_torso = self.ctrl.update(world.q, world.v)
            world.send(taus, tau_torso, self.head_target)
            t1 = time.perf_counter()
            part[1] = t1 - t0
            world.sense()
            self._count_away(world.time)
            self.head[:2] = world.head_set
            t_step = time.perf_counter()
            self.waited_s = t_step - t1
        elif self.plant is not None:
            self.plant.cycle()  # the hands' and the head's servo steps too
            t1 = time.perf_counter()
            part[1] = t1 - t0 - self.plant.parts[1]
        else:
            self.hands.step(data, DT)
            self._step_head()
            q, v = self.q(), self.v()
            taus, tau_torso = self.ctrl.update(q, v)
            for s in SIDES:
                data.ctrl[self.arm_act[s]] = taus[s]
            data.ctrl[self.torso_act] = tau_torso
            t_step = time.perf_counter()
            part[1] = t_step - t0
            mujoco.mj_step(self.model, data)
            t1 = time.perf_counter()
        self.cycles += 1
        self.loads.follow(self.held, self.cycles, self.grip, self.ft_force)
        # each hand is scanned every CONTACT_PERIOD cycles, the two half a period apart, so
        # that no cycle carries both scans
        phase = self.cycles % CONTACT_PERIOD
        if phase == self._self_phase:
            pairs = self.self_contacts_now()
            if pairs:
                self._count_self_contacts(pairs)
        elif phase in self._scan_phase:
            s = self._scan_phase[phase]
            self.touch[s] = self.touching(s)
            b = self.held[s]
            if b is not None and self.touch[s].get(b, 0) == 0:
                self.lost_cycles[s] += 1
            else:
                self.lost_cycles[s] = 0
        part[2] = time.perf_counter() - t1 + (self.plant.parts[1] if self.plant is not None else t1 - t_step)

    def _count_away(self, now: float) -> None:
        """Add to ``away_s`` the time between two states that the world stepped without this
        controller: past the ``HOLD_CYCLES`` states a late command still answers, the world's
        safety layer held the robot (velma/world/serve.py)."""
        gap = now - self._sensed_at
        if gap > AWAY_GAP_S:
            self.away_s += gap - DT
        self._sensed_at = now

    def _step_head(self) -> None:
        """The head's servo setpoints one step (≤ HEAD_RATE·DT per joint) towards ``head_target``."""
        ramp(self.head_set, self.head_target, HEAD_RATE * DT)
        self.data.ctrl[list(self.head_act)] = self.head_set

    def touching(self, side: str) -> dict[int, int]:
        """{body id: count of distinct hand geoms of ``side`` touching it} now (velma/control/hand.py
        ``ContactMonitor.touching``; compiled with the plant; the world's last scan when
        attached to one)."""
        if self.world is not None:
            return self.world.touching(side)
        if self.plant is not None:
            return self.plant.touching(side)
        return self.contacts.touching(self.data, side)

    def arm_touches(self, side: str) -> list[str]:
        """What ``side``'s arm links (not its hand) touch outside the robot now, as ``LINK on
        GEOM`` (sorted, distinct): a Cartesian motion that stops short of its goal is usually
        held by such a contact. From a scratch copy of the kitchen at its present positions
        (MuJoCo's collision detection, penetrating contacts only); a few ms: for a failure's
        reason, not for every cycle."""
        model = self.model
        scratch = mujoco.MjData(model)
        scratch.qpos[:] = self.data.qpos
        mujoco.mj_fwdPosition(model, scratch)
        prefix, found = f"{side}_arm_", set()
        for contact in scratch.contact[: scratch.ncon]:
            if contact.dist > 0.0:
                continue
            for mine, other in ((contact.geom1, contact.geom2), (contact.geom2, contact.geom1)):
                link, touched = model.body(model.geom_bodyid[mine]).name, int(model.geom_bodyid[other])
                if link.startswith(prefix) and not self.contacts.robot_body[touched]:
                    found.add(f"{link} on {model.geom(other).name or model.body(touched).name}")
        return sorted(found)

    def self_contacts_now(self) -> list[tuple[int, int]]:
        """(geom, geom) of each contact of the robot with itself now (``ContactMonitor.self_contacts``)."""
        if self.world is not None:
            return self.world.self_contacts()
        if self.plant is not None:
            return self.plant.self_contacts()
        return self.contacts.self_contacts(self.data)

    def _count_self_contacts(self, pairs: list[tuple[int, int]]) -> None:
        self.self_contacts += 1
        for a, b in set(pairs):
            names = tuple(sorted(self._geom_name(g) for g in (a, b)))
            key = (names[0], names[1])
            self.self_contact_pairs[key] = self.self_contact_pairs.get(key, 0) + 1

    def _geom_name(self, geom: int) -> str:
        name = self.model.geom(geom).name
        return name or self.model.body(int(self.model.geom_bodyid[geom])).name

    def displace(self, body: str, delta: tuple[float, float, float], tilt: float = 0.0) -> None:
        """Move free body ``body`` by ``delta`` (world, m), turn it by ``tilt`` (rad) about the
        world's x axis through its origin, and stop it: a disturbance of the simulated world (a
        person moves or knocks over an object), not a robot action (velma/world/hardware.py
        ``displace``). Attached to a world process, the world takes it with the next command.
        Raises KeyError for a body that is not in the scene, ValueError for one without a free
        joint."""
        try:
            b = int(self.model.body(body).id)
        except KeyError:
            raise KeyError(f"no body {body!r} in the scene") from None
        if not is_free(self.model, b):
            raise ValueError(f"{body} is not a free body")
        if self.world is not None:
            self.world.disturb(b, delta, tilt)
        else:
            displace(self.model, self.data, b, delta, tilt)

    def torso_angle_cmd(self) -> float:
        """Commanded torso angle (rad)."""
        return self.ctrl.torso_q

    def arm_names(self, side: str) -> tuple[str, ...]:
        """Arm joint names of ``side``."""
        return arm_joints(side)

    @staticmethod
    def torso_joint() -> str:
        """Name of the torso joint."""
        return TORSO_JOINT
