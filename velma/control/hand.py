"""BarrettHand BH8-282 position control with the proximal/distal coupling and the breakaway
clutch, and contact monitoring of the hand against the scene.

Each finger's proximal and distal joints have force-limited position servos (velma.xml); this
module writes their setpoints, and one spread value for both spread joints
(velma/model/README.md "BarrettHand BH8-282": the two spread joints share one command). Closing
ramps the proximal setpoints at ``CLOSE_RATE`` towards the target.

Coupling and breakaway (velma/model/README.md "BarrettHand BH8-282": the distal joint follows
the proximal at a third of its angle; the proximal link stops when it meets resistance, about 1
N·m, and the distal link keeps closing):

- A free finger is coupled: distal setpoint = proximal setpoint / 3.
- While a finger closes, its clutch *breaks away* when the proximal servo's torque reaches
  ``BREAKAWAY_TORQUE`` (1 N·m): the link met resistance. From then on the proximal setpoint
  stops ramping: it is held at ``measured angle + BREAKAWAY_TORQUE / kp``, so the proximal
  link stays where the object stopped it and presses on it with ≈ the breakaway torque (a
  slipping clutch transmits its slip torque). The setpoint only ratchets closed: if the
  object yields, the link follows it with that torque; if the object pushes the link open,
  the setpoint stays and the servo resists up to its own limit (the real hand's worm gear is
  not back-drivable). Meanwhile the distal setpoint keeps closing at ``CLOSE_RATE / 3`` (the
  motor keeps turning; only the distal link moves) up to its limit ``DISTAL_MAX``
  (0.8377 rad); the distal servo's torque limit (0.6 N·m) caps its force on the object.
- Opening (a command whose target is below a finger's current proximal setpoint) re-engages
  the clutch: the distal setpoint returns to proximal / 3 at ``OPEN_RATE`` and the finger is
  coupled again.

The compiled plant steps the same setpoints in C++ (velma/control/_plant.hpp
``Plant.bind_servos``, on ``Hands.state``); ``Hands.step`` is its reference
(tests/velma/test_plant.py compares the two bit for bit).

Simplifications (named): the clutch is decided from the simulated servo torque, per finger,
with no hysteresis beyond "opening resets it"; grip force comes from servo torque limits, not
from a force controller; the distal link's own breakaway (none on the real hand) is not
modelled.
"""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt

from velma.control.joints import ROBOT_ROOT, SIDES, Array, distal_joints, proximal_joints, spread_joints

PROXIMAL_MAX = 2.4434  # rad (velma/model/README.md "BarrettHand BH8-282")
DISTAL_MAX = 0.8377  # rad (velma/model/README.md "BarrettHand BH8-282")
DISTAL_RATIO = 1.0 / 3.0  # distal = proximal / 3 (velma/model/README.md "BarrettHand BH8-282")
BREAKAWAY_TORQUE = 1.0  # N·m, proximal torque at which the clutch slips (velma/model/README.md)
CLOSE_RATE = 1.5  # rad/s, proximal setpoint rate while closing (real finger ≤ 3.27 rad/s)
OPEN_RATE = 2.0  # rad/s
SPREAD_RATE = 1.5  # rad/s
STALL_SPEED = 0.03  # rad/s: below this a closing finger counts as stalled


# One hand's setpoints as a row of ``Hands.state`` (float64), the layout the compiled plant
# shares (velma/control/_plant.hpp ``Plant.bind_servos``): spread, spread target, proximal (3),
# target (3), distal (3), broken (3, 0 or 1), steady (0 or 1).
SPREAD, SPREAD_TARGET, PROXIMAL, TARGET, DISTAL, BROKEN, STEADY, HAND_WIDTH = 0, 1, 2, 5, 8, 11, 14, 15


class HandSetpoint:
    """Setpoints of one hand, kept in a row of ``Hands.state`` (layout above).

    ``spread`` / ``spread_target``: commanded and final spread (rad); ``proximal`` (3,) rad:
    the proximal setpoints of fingers One, Two, Three; ``target`` (3,) rad: where they are
    ramping to; ``distal`` (3,) rad: the distal setpoints; ``broken`` (3,) bool: the finger's
    clutch has broken away (proximal stopped at the object, distal closing on its own);
    ``steady``: every setpoint has reached its target and no clutch has broken away, so a
    step would change nothing (``Hands.step`` then skips the hand: the cycle's
    budget). The arrays read are copies; assigning one writes the row."""

    __slots__ = ("row",)

    def __init__(self, row: Array | None = None) -> None:
        self.row: Array = np.zeros(HAND_WIDTH) if row is None else row

    @property
    def spread(self) -> float:
        return float(self.row[SPREAD])

    @spread.setter
    def spread(self, value: float) -> None:
        self.row[SPREAD] = value

    @property
    def spread_target(self) -> float:
        return float(self.row[SPREAD_TARGET])

    @spread_target.setter
    def spread_target(self, value: float) -> None:
        self.row[SPREAD_TARGET] = value

    @property
    def proximal(self) -> Array:
        return self.row[PROXIMAL:TARGET].copy()

    @proximal.setter
    def proximal(self, value: npt.ArrayLike) -> None:
        self.row[PROXIMAL:TARGET] = value

    @property
    def target(self) -> Array:
        return self.row[TARGET:DISTAL].copy()

    @target.setter
    def target(self, value: npt.ArrayLike) -> None:
        self.row[TARGET:DISTAL] = value

    @property
    def distal(self) -> Array:
        return self.row[DISTAL:BROKEN].copy()

    @distal.setter
    def distal(self, value: npt.ArrayLike) -> None:
        self.row[DISTAL:BROKEN] = value

    @property
    def broken(self) -> npt.NDArray[np.bool_]:
        out: npt.NDArray[np.bool_] = self.row[BROKEN:STEADY] != 0.0
        return out

    @broken.setter
    def broken(self, value: npt.ArrayLike) -> None:
        self.row[BROKEN:STEADY] = np.asarray(value, dtype=bool)

    @property
    def steady(self) -> bool:
        return bool(self.row[STEADY])

    @steady.setter
    def steady(self, value: bool) -> None:
        self.row[STEADY] = 1.0 if value else 0.0


class Hands:
    """Setpoints and MuJoCo actuator/joint indices of both hands.

    Raises ``KeyError`` if ``model`` lacks one of the hand servos (``…KnuckleOneServo``,
    ``…KnuckleTwoServo``, ``…KnuckleThreeServo``) or joints."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.state = np.zeros((len(SIDES), HAND_WIDTH))
        """Both hands' setpoints (float64, (2, HAND_WIDTH), rows in ``SIDES`` order): the
        storage of ``set`` (and of the compiled plant's servo step, velma/executor/plant.py)."""
        self.set = {s: HandSetpoint(self.state[k]) for k, s in enumerate(SIDES)}

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
        self.prox_act = {
            s: np.array([act(j.replace("Joint", "Servo")) for j in proximal_joints(s)], dtype=np.int64)
            for s in SIDES
        }
        self.dist_act = {
            s: np.array([act(j.replace("Joint", "Servo")) for j in distal_joints(s)], dtype=np.int64)
            for s in SIDES
        }
        self.prox_q = {s: qadr(proximal_joints(s)) for s in SIDES}
        self.prox_v = {s: dadr(proximal_joints(s)) for s in SIDES}
        self.dist_q = {s: qadr(distal_joints(s)) for s in SIDES}
        self.spread_q = {s: qadr(spread_joints(s)) for s in SIDES}
        # proximal servo stiffness (N·m/rad), for the frozen setpoint after breakaway
        self.prox_kp = {s: model.actuator_gainprm[self.prox_act[s], 0].copy() for s in SIDES}

    def reset_from(self, data: mujoco.MjData) -> None:
        """Setpoints = current joint positions (no jump when the loop starts); clutches
        engaged."""
        for s in SIDES:
            hs = self.set[s]
            hs.proximal = data.qpos[self.prox_q[s]].copy()
            hs.target = hs.proximal.copy()
            hs.distal = data.qpos[self.dist_q[s]].copy()
            hs.broken = np.zeros(3, dtype=bool)
            hs.spread = hs.spread_target = float(data.qpos[self.spread_q[s][0]])
            hs.steady = False

    def command(self, side: str, proximal: float, spread: float | None = None) -> None:
        """Ramp ``side``'s proximal setpoints to ``proximal`` (rad, clipped to 0..PROXIMAL_MAX)
        and the spread to ``spread`` (rad, clipped to 0..π; unchanged if None). A finger whose
        target is below its current proximal setpoint is opening: its clutch re-engages.
        Raises ``KeyError`` for an unknown side."""
        hs = self.set[side]
        hs.steady = False
        hs.target = np.full(3, float(np.clip(proximal, 0.0, PROXIMAL_MAX)))
        hs.broken = hs.broken & ~(hs.target < hs.proximal)
        if spread is not None:
            hs.spread_target = float(np.clip(spread, 0.0, np.pi))

    def keep(self, side: str) -> None:
        """Keep ``side``'s hand as it is (a halted grasp or release, velma/executor/loop.py
        ``ControlLoop.cancel``): the proximal targets become the current proximal setpoints and
        the spread target the current spread, so a closing hand stops closing and an opening
        one stops opening; a finger whose clutch broke away keeps pressing on what stopped it
        (module docstring). Raises ``KeyError`` for an unknown side."""
        hs = self.set[side]
        hs.target = hs.proximal.copy()
        hs.spread_target = hs.spread
        hs.steady = False

    def step(self, data: mujoco.MjData, dt: float) -> None:
        """Advance the ramps and the clutches by ``dt`` (s) from the state in ``data``
        (measured proximal angles and servo torques), and write the servo controls into
        ``data.ctrl`` (rad). A steady hand (``HandSetpoint.steady``) is skipped: its controls
        in ``data.ctrl`` are already the ones a step would write."""
        for s in SIDES:
            hs = self.set[s]
            if hs.steady:
                continue
            # three fingers in plain floats: the same IEEE operations as numpy's on (3,)
            # arrays, at a fraction of the per-call cost (the cycle's budget)
            proximal = hs.proximal.tolist()
            target = hs.target.tolist()
            distal = hs.distal.tolist()
            broken = hs.broken.tolist()
            torque = data.actuator_force[self.prox_act[s]].tolist()
            delta = [t - p for t, p in zip(target, proximal, strict=True)]
            closing = [d > 0 for d in delta]
            slip = [
                c and not b and f >= BREAKAWAY_TORQUE for c, b, f in zip(closing, broken, torque, strict=True)
            ]
            if any(slip) or any(broken):
                # the setpoint at which the proximal servo pushes with the breakaway torque
                measured = data.qpos[self.prox_q[s]].tolist()
                kp = self.prox_kp[s].tolist()
                press = [m + BREAKAWAY_TORQUE / k for m, k in zip(measured, kp, strict=True)]
                for i in range(3):
                    follow = min(max(proximal[i], press[i]), target[i])  # ratchet: never back
                    if broken[i]:
                        proximal[i] = follow
                    elif slip[i]:
                        proximal[i] = min(proximal[i], press[i])
                    broken[i] = broken[i] or slip[i]
            goal = [0.0] * 3
            for i in range(3):
                if not broken[i]:
                    rate = (CLOSE_RATE if closing[i] else OPEN_RATE) * dt
                    proximal[i] = proximal[i] + min(max(delta[i], -rate), rate)
                    goal[i] = proximal[i] * DISTAL_RATIO
                    distal_rate = OPEN_RATE * dt
                else:
                    goal[i] = DISTAL_MAX
                    distal_rate = CLOSE_RATE * DISTAL_RATIO * dt
                distal[i] = distal[i] + min(max(goal[i] - distal[i], -distal_rate), distal_rate)
            ds = hs.spread_target - hs.spread
            hs.spread += min(max(ds, -SPREAD_RATE * dt), SPREAD_RATE * dt)
            hs.proximal = np.array(proximal)
            hs.distal = np.array(distal)
            hs.broken = np.array(broken, dtype=bool)
            for a in self.spread_act[s]:
                data.ctrl[a] = hs.spread
            data.ctrl[self.prox_act[s]] = hs.proximal
            data.ctrl[self.dist_act[s]] = hs.distal
            hs.steady = (
                hs.spread == hs.spread_target and not any(broken) and proximal == target and distal == goal
            )

    def proximal(self, data: mujoco.MjData, side: str) -> Array:
        """Measured proximal angles (3,) rad."""
        out: Array = data.qpos[self.prox_q[side]]
        return out

    def distal(self, data: mujoco.MjData, side: str) -> Array:
        """Measured distal angles (3,) rad."""
        out: Array = data.qpos[self.dist_q[side]]
        return out

    def proximal_speed(self, data: mujoco.MjData, side: str) -> Array:
        """Measured proximal speeds (3,) rad/s."""
        out: Array = data.qvel[self.prox_v[side]]
        return out

    def broken_away(self, side: str) -> npt.NDArray[np.bool_]:
        """(3,) bool: which fingers' clutches have broken away (a copy)."""
        return self.set[side].broken.copy()

    def ramp_done(self, side: str) -> bool:
        """True when the spread setpoint and every finger's proximal setpoint have reached
        their targets; a finger whose clutch broke away counts as done (it met the object)."""
        hs = self.set[side]
        prox_done = (hs.proximal == hs.target) | hs.broken
        return bool(np.all(prox_done)) and hs.spread == hs.spread_target


class ContactMonitor:
    """Which scene bodies touch each hand (finger links and palm), from ``data.contact``.

    ``touching(data, side)`` returns {body id: number of distinct hand geoms touching it};
    only bodies outside the robot are reported.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.hand_side = np.full(model.ngeom, -1, dtype=np.int64)
        robot_bodies = set()
        root = model.body(ROBOT_ROOT).id
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
        # a geom's part for self-collision: -1 outside the robot, the side's index for a hand
        # geom, 2 for every other robot geom (contacts within one hand are the hand's own)
        self.part = np.where(self.robot_body[self.geom_body], 2, -1)
        self.part[self.hand_side >= 0] = self.hand_side[self.hand_side >= 0]

    def self_contacts(self, data: mujoco.MjData) -> list[tuple[int, int]]:
        """The robot touching itself: (geom, geom) of each contact between two robot geoms
        that are not both in one hand (self-collision is on in velma.xml)."""
        n = data.ncon
        if n == 0:
            return []
        geoms = data.contact.geom[:n]
        p0, p1 = self.part[geoms[:, 0]], self.part[geoms[:, 1]]
        hit = (p0 >= 0) & (p1 >= 0) & ((p0 != p1) | (p0 == 2))
        if not hit.any():
            return []
        return [(int(a), int(b)) for a, b in geoms[hit]]

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
