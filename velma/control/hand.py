"""BarrettHand BH8-282 position control with the proximal/distal coupling, and contact
monitoring of the hand against the scene.

Each finger's proximal and distal joints have force-limited position servos (velma.xml);
this module commands ``distal = proximal / 3`` (velma-facts.md coupling) and one spread value
for both spread joints. Closing ramps the proximal setpoints at ``CLOSE_RATE`` towards the
limit; a finger that meets the object stops because its servo saturates (force limit
1.5 N·m proximal, 0.6 N·m distal), and the saturated servo is the grip force.

Simplifications (named): the breakaway clutch is not modelled (the distal joint does not
keep closing after the proximal stalls, beyond its own servo's travel); grip force comes
from servo saturation, not from a force controller.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt

from velma.control.robot_model import SIDES, Array, distal_joints, proximal_joints, spread_joints

PROXIMAL_MAX = 2.4434  # rad
DISTAL_RATIO = 1.0 / 3.0
CLOSE_RATE = 1.5  # rad/s, proximal setpoint rate while closing (real finger ≤ 3.27 rad/s)
OPEN_RATE = 2.0  # rad/s
SPREAD_RATE = 1.5  # rad/s
STALL_SPEED = 0.03  # rad/s: below this a closing finger counts as stalled


@dataclass
class HandSetpoint:
    """Commanded spread (rad) and proximal angles (3,) rad of one hand; ``target`` is where
    the proximal setpoints are ramping to."""

    spread: float = 0.0
    spread_target: float = 0.0
    proximal: Array = field(default_factory=lambda: np.zeros(3))
    target: Array = field(default_factory=lambda: np.zeros(3))


class Hands:
    """Setpoints and MuJoCo actuator/joint indices of both hands."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.set = {s: HandSetpoint() for s in SIDES}

        def act(name: str) -> int:
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
            if i < 0:
                raise KeyError(name)
            return int(i)

        def qadr(names: tuple[str, ...]) -> npt.NDArray[np.int64]:
            return np.array([model.joint(n).qposadr[0] for n in names], dtype=np.int64)

        def dadr(names: tuple[str, ...]) -> npt.NDArray[np.int64]:
            return np.array([model.joint(n).dofadr[0] for n in names], dtype=np.int64)

        self.spread_act = {s: [act(j.replace("Joint", "Servo")) for j in spread_joints(s)] for s in SIDES}
        self.prox_act = {s: [act(j.replace("Joint", "Servo")) for j in proximal_joints(s)] for s in SIDES}
        self.dist_act = {s: [act(j.replace("Joint", "Servo")) for j in distal_joints(s)] for s in SIDES}
        self.prox_q = {s: qadr(proximal_joints(s)) for s in SIDES}
        self.prox_v = {s: dadr(proximal_joints(s)) for s in SIDES}
        self.spread_q = {s: qadr(spread_joints(s)) for s in SIDES}

    def reset_from(self, data: mujoco.MjData) -> None:
        """Setpoints = current joint positions (no jump when the loop starts)."""
        for s in SIDES:
            hs = self.set[s]
            hs.proximal = data.qpos[self.prox_q[s]].copy()
            hs.target = hs.proximal.copy()
            hs.spread = hs.spread_target = float(data.qpos[self.spread_q[s][0]])

    def command(self, side: str, proximal: float, spread: float | None = None) -> None:
        """Ramp ``side``'s proximal setpoints to ``proximal`` (rad) and the spread to
        ``spread`` (rad, unchanged if None)."""
        hs = self.set[side]
        hs.target = np.full(3, float(np.clip(proximal, 0.0, PROXIMAL_MAX)))
        if spread is not None:
            hs.spread_target = float(np.clip(spread, 0.0, np.pi))

    def step(self, data: mujoco.MjData, dt: float) -> None:
        """Advance the ramps by ``dt`` (s) and write the servo controls into ``data.ctrl``."""
        for s in SIDES:
            hs = self.set[s]
            delta = hs.target - hs.proximal
            rate = np.where(delta > 0, CLOSE_RATE, OPEN_RATE) * dt
            hs.proximal = hs.proximal + np.clip(delta, -rate, rate)
            ds = hs.spread_target - hs.spread
            hs.spread += float(np.clip(ds, -SPREAD_RATE * dt, SPREAD_RATE * dt))
            for a in self.spread_act[s]:
                data.ctrl[a] = hs.spread
            data.ctrl[self.prox_act[s]] = hs.proximal
            data.ctrl[self.dist_act[s]] = hs.proximal * DISTAL_RATIO

    def proximal(self, data: mujoco.MjData, side: str) -> Array:
        """Measured proximal angles (3,) rad."""
        out: Array = data.qpos[self.prox_q[side]]
        return out

    def proximal_speed(self, data: mujoco.MjData, side: str) -> Array:
        """Measured proximal speeds (3,) rad/s."""
        out: Array = data.qvel[self.prox_v[side]]
        return out

    def ramp_done(self, side: str) -> bool:
        """True when the proximal and spread setpoints have reached their targets."""
        hs = self.set[side]
        return bool(np.all(hs.proximal == hs.target)) and hs.spread == hs.spread_target


class ContactMonitor:
    """Which scene bodies touch each hand (finger links and palm), from ``data.contact``.

    ``touching(data, side)`` returns {body id: number of distinct hand geoms touching it};
    only bodies outside the robot are reported.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.hand_side = np.full(model.ngeom, -1, dtype=np.int64)
        robot_bodies = set()
        root = model.body("torso_base").id
        for b in range(model.nbody):
            x = b
            while x != 0 and x != root:
                x = model.body_parentid[x]
            if x == root:
                robot_bodies.add(b)
        self.robot_body = np.zeros(model.nbody, dtype=bool)
        self.robot_body[list(robot_bodies)] = True
        for side_i, side in enumerate(SIDES):
            palm = model.body(f"{side}_HandPalmLink").id
            for g in range(model.ngeom):
                x = int(model.geom_bodyid[g])
                while x not in (0, palm):
                    x = int(model.body_parentid[x])
                if x == palm:
                    self.hand_side[g] = side_i
        self.geom_body = model.geom_bodyid.copy()

    def touching(self, data: mujoco.MjData, side: str) -> dict[int, int]:
        """{body id: count of distinct hand geoms of ``side`` in contact with it}."""
        n = data.ncon
        if n == 0:
            return {}
        geoms = data.contact.geom[:n]
        side_i = SIDES.index(side)
        out: dict[int, set[int]] = {}
        for col in (0, 1):
            mine = self.hand_side[geoms[:, col]] == side_i
            if not np.any(mine):
                continue
            other = geoms[mine, 1 - col]
            hand_geoms = geoms[mine, col]
            bodies = self.geom_body[other]
            for b, g in zip(bodies.tolist(), hand_geoms.tolist(), strict=True):
                if not self.robot_body[b]:
                    out.setdefault(b, set()).add(g)
        return {b: len(g) for b, g in out.items()}
