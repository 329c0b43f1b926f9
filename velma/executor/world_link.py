"""The controller's side of the robot link (velma/world/link.py): ag_ex's loop attached to a
world process, as a KUKA controller is to the arm under FRI.

Each cycle the loop sends the impedance law's torques, the hands' operations, the head's
targets and any disturbance (velma/world/layout.py ``COMMAND``), then waits for the world's
next measured state. When something reads poses (the state published to the agents, a
guarded move's wrist force, the head camera's capture) the world's scene is copied into a
mirror of the kitchen's MuJoCo data (``mirror``: the scene's ``qpos``, the robot's measured
joint velocities and wrist wrenches, then ``mj_kinematics``), at most once a cycle. The
mirror is never stepped. The hands' and the head's servos run in the world; the loop keeps their
setpoint rows as the world reports them (``LinkedHands``).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import numpy.typing as npt

from velma.control.hand import PROXIMAL_MAX, TARGET, Hands
from velma.control.joints import SIDES, JointMap, robot_joints
from velma.world.layout import COMMAND, HAND_KEEP, HAND_MOVE, HAND_OP, MEASURED, TOUCH_SLOTS
from velma.world.link import RobotLink

Array = npt.NDArray[np.float64]

ATTACH_TIMEOUT_S = 120.0
"""How long (s) a controller waits for the world's first measured state (the world builds
the kitchen first: seconds)."""
SENSE_WAIT_S = 0.2
"""How long (s) one cycle waits for the world's next state before it goes on without one (a
world that stopped or is gone: the loop keeps taking commands and signals)."""


class LinkedHands(Hands):
    """The BarrettHands seen from the controller: ``command`` and ``keep`` change the setpoint
    rows as ``Hands`` does and become operations with sequence numbers in the link's command
    (``COMMAND`` ``hand``); the rows follow the world's once it has taken the latest
    operation (``sync``). ``step`` is the world's: not called here."""

    def __init__(self, model: mujoco.MjModel, ops: Array) -> None:
        super().__init__(model)
        self.ops = ops
        """The ``hand`` field of the link's command (a view, ``HAND_OP`` values per side)."""
        self.seq = np.zeros(len(SIDES))

    def command(self, side: str, proximal: float, spread: float | None = None) -> None:
        super().command(side, proximal, spread)
        self._op(side, HAND_MOVE, proximal, math.nan if spread is None else spread)

    def keep(self, side: str) -> None:
        super().keep(side)
        self._op(side, HAND_KEEP, math.nan, math.nan)

    def _op(self, side: str, op: float, proximal: float, spread: float) -> None:
        k = SIDES.index(side)
        self.seq[k] += 1.0
        self.ops[HAND_OP * k : HAND_OP * (k + 1)] = (self.seq[k], op, proximal, spread)

    def sync(self, rows: Array, taken: Array) -> None:
        """Take the world's setpoint rows (``MEASURED`` ``hand``) of each hand that has taken
        this side's latest operation (``taken``: ``MEASURED`` ``hand_seq``)."""
        for k in range(len(SIDES)):
            if taken[k] == self.seq[k]:
                self.state[k] = rows[k]

    def continue_from(self, rows: Array, taken: Array) -> None:
        """Start from the world's hands as they are: their rows, and sequence numbers that go
        on from the last the world took (a restarted controller re-sends nothing)."""
        self.seq[:] = taken
        for k in range(len(SIDES)):
            self.ops[HAND_OP * k] = taken[k]
        self.state[:] = rows


class WorldLink:
    """The link to a world process, and the mirror of its kitchen (module docstring).

    ``link`` is attached (``RobotLink.attach``); ``model`` and ``data`` are the controller's
    copy of the kitchen (same model as the world's: raises ValueError when the scene's size
    differs); ``jmap`` maps the link's joints to them, in Pinocchio's order, which must be the
    world's (velma/control/joints.py ``robot_joints``: ValueError when it is not). Raises
    RuntimeError when the world publishes nothing within ``timeout_s``."""

    def __init__(
        self,
        link: RobotLink,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        jmap: JointMap,
        *,
        timeout_s: float = ATTACH_TIMEOUT_S,
        spin_s: float = 0.0,
    ) -> None:
        if link.n_measured != MEASURED.size or link.n_command != COMMAND.size:
            raise ValueError(
                f"the link carries {link.n_measured} measured and {link.n_command} command values, "
                f"this controller {MEASURED.size} and {COMMAND.size}"
            )
        if link.n_scene != 1 + model.nq:
            raise ValueError(f"the world's scene has {link.n_scene - 1} coordinates, this kitchen {model.nq}")
        if not np.array_equal(JointMap.build(model, robot_joints(model)).qpos_adr, jmap.qpos_adr):
            raise ValueError("the world orders the robot's joints otherwise than this controller")
        self.link, self.model, self.data, self.jmap = link, model, data, jmap
        self.spin_s = spin_s
        self.measured, self.scene = np.zeros(MEASURED.size), np.zeros(link.n_scene)
        self.command = np.zeros(COMMAND.size)
        self.hands = LinkedHands(model, self.command[COMMAND.slice("hand")])
        self._tau, self._head = COMMAND.slice("tau"), COMMAND.slice("head")
        self._disturb = self.command[COMMAND.slice("disturb")]
        self.q: Array = self.measured[MEASURED.slice("q")]
        """The measured joint positions (rad, (33,), Pinocchio's order; a view, rewritten each cycle)."""
        self.v: Array = self.measured[MEASURED.slice("v")]
        """The measured joint velocities (rad/s, (33,); a view)."""
        self.head_set: Array = self.measured[MEASURED.slice("head")]
        """The head servos' setpoints (rad: pan, tilt; a view)."""
        self._hand_rows = self.measured[MEASURED.slice("hand")].reshape(len(SIDES), -1)
        self._hand_seq = self.measured[MEASURED.slice("hand_seq")]
        self._ft = self.measured[MEASURED.slice("ft")].reshape(len(SIDES), 6)
        self._touch = self.measured[MEASURED.slice("touch")].reshape(len(SIDES), TOUCH_SLOTS, 2)
        self._self_touch = self.measured[MEASURED.slice("self_touch")].reshape(-1, 2)
        self._holding, self._time = MEASURED.fields["holding"][0], MEASURED.fields["time"][0]
        self.ft_adr = [
            (int(model.sensor(f"{s}_ft_force").adr[0]), int(model.sensor(f"{s}_ft_torque").adr[0]))
            for s in SIDES
        ]
        self.cycle = -1
        """The world cycle of the measured state in hand (−1: none yet)."""
        self.stale = True
        """True when the mirror is older than the measured state (``mirror`` brings it up)."""
        self.silent = 0
        """Cycles in a row that found no new state (the world stopped or is gone)."""
        if not link.wait_measured(0, timeout_s, spin_s=0.0):
            raise RuntimeError(f"the world published nothing on link {link.name} within {timeout_s:.0f} s")
        data.qvel[:] = 0.0  # the scene carries positions only: the objects' velocities are not mirrored
        self._read()
        self.mirror()
        self.hands.continue_from(self._hand_rows, self._hand_seq)
        self.command[COMMAND.fields["disturb"][0]] = self.measured[MEASURED.fields["disturb_seq"][0]]

    @property
    def time(self) -> float:
        """The world's time of the measured state (s)."""
        return float(self.measured[self._time])

    @property
    def holding(self) -> bool:
        """True while the world's safety layer holds the robot (no command came in time)."""
        return bool(self.measured[self._holding])

    def send(self, taus: dict[str, Array], tau_torso: float, head_target: Array) -> None:
        """Command the world: arm torques per side (N·m, (7,)), the torso's (N·m), the head's
        targets (rad, (2,)), with the hands' operations and the disturbance as they stand;
        answers the measured state in hand."""
        tau = self.command[self._tau]
        for k, side in enumerate(SIDES):
            tau[7 * k : 7 * k + 7] = taus[side]
        tau[-1] = tau_torso
        self.command[self._head] = head_target
        self.link.command(max(self.cycle, 0), self.command)

    def sense(self) -> bool:
        """Wait (≤ ``SENSE_WAIT_S``) for the world's next state and mirror it; False when none
        came (``silent`` counts such cycles)."""
        if not self.link.wait_measured(self.cycle + 1, SENSE_WAIT_S, self.spin_s):
            self.silent += 1
            return False
        self.silent = 0
        self._read()
        return True

    def _read(self) -> None:
        cycle = self.link.read_measured(self.measured)
        if cycle is None:
            return  # a write left half done by a world that was killed: keep the last state
        self.cycle = cycle
        self.stale = True
        self.hands.sync(self._hand_rows, self._hand_seq)

    def mirror(self) -> None:
        """Bring the mirror up to the world's latest scene (module docstring)."""
        self.stale = False
        if self.link.read_scene(self.scene) is None:
            return
        data, jmap = self.data, self.jmap
        data.time = self.scene[0]
        data.qpos[:] = self.scene[1:]
        data.qvel[jmap.dof_adr] = self.v
        for k, (force, torque) in enumerate(self.ft_adr):
            data.sensordata[force : force + 3] = self._ft[k, :3]
            data.sensordata[torque : torque + 3] = self._ft[k, 3:]
        mujoco.mj_kinematics(self.model, data)

    def touching(self, side: str) -> dict[int, int]:
        """{body id: number of ``side``'s hand geoms touching it} as the world's last tactile
        scan of that hand found it (velma/world/layout.py ``touch``)."""
        slots = self._touch[SIDES.index(side)]
        return {int(b): int(n) for b, n in slots.tolist() if b >= 0}

    def self_contacts(self) -> list[tuple[int, int]]:
        """(geom, geom) of each contact of the robot with itself in the world's last scan."""
        return [(int(a), int(b)) for a, b in self._self_touch.tolist() if a >= 0]

    def disturb(self, body: int, delta: tuple[float, float, float], tilt: float) -> None:
        """Have the world move free body id ``body`` by ``delta`` (m, world) and turn it by
        ``tilt`` (rad, about world x) with the next command (velma/world/hardware.py
        ``displace``)."""
        self._disturb[:] = (self._disturb[0] + 1.0, body, *delta, tilt)

    def grasped(self, side: str) -> int | None:
        """The body ``side``'s hand holds as the world reports it: the most touched one while
        the hand is closing on it (every proximal target at ``PROXIMAL_MAX``, as a Grasp sets
        them); None otherwise. How a restarted controller learns what it holds."""
        if not bool(np.all(self.hands.state[SIDES.index(side), TARGET : TARGET + 3] >= PROXIMAL_MAX - 1e-6)):
            return None
        touch = self.touching(side)
        return max(touch, key=lambda b: touch[b]) if touch else None
