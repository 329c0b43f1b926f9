"""What crosses the robot link each cycle (velma/world/link.py), number by number: the
robot's measured state from the world, the command back from the controller.

Joints are in Pinocchio's velocity order (velma/control/joints.py ``robot_joints``: the
torso, both arms, the head and the hands' joints, 33 in all), sides in ``SIDES`` order
(right, left). SI units: s, rad, rad/s, N, N·m.

Measured (``MEASURED``):

- ``time``: the world's simulated time (s);
- ``q``, ``v``: joint positions (rad) and velocities (rad/s), what the encoders read;
- ``ft``: per side the wrist force/torque sensor's wrench (fx, fy, fz N, tx, ty, tz N·m) in the
  sensor frame (``<side>_ft_sensor``);
- ``touch``: per side ``TOUCH_SLOTS`` pairs (body id, number of the hand's geoms touching it;
  −1, 0 for an empty slot): the hand's tactile sensing. Naming the touched body is a
  simplification (a BarrettHand's pads feel pressure, not objects);
- ``holding``: 1 while the world's safety layer holds the robot (no command came in time), else 0;
- ``hand``: per side the hand's servo state, a ``HAND_WIDTH`` row of velma/control/hand.py
  (spread and its target, proximal setpoints and targets, distal setpoints, broken-away
  clutches, steady), as a BarrettHand reports its motors;
- ``hand_seq``: per side the sequence number of the last hand command the hand took;
- ``self_touch``: ``SELF_SLOTS`` pairs of geom ids of the robot touching itself (−1: an empty
  slot), rewritten every ``CONTACT_PERIOD`` cycles (velma/world/hardware.py);
- ``head``: the head servos' setpoints (pan, tilt; rad), ramping to the commanded targets;
- ``disturb_seq``: the sequence number of the last disturbance the world took.

Command (``COMMAND``):

- ``tau``: per side the 7 arm joint torques (N·m), then the torso's;
- ``hand``: per side ``HAND_OP`` values: a sequence number, the operation (``HAND_MOVE``: ramp
  to the proximal target and the spread target, rad, NaN spread: keep it; ``HAND_KEEP``: stop
  where the setpoints are), the proximal target, the spread target. The hand takes an
  operation once, when its sequence number changes (velma/control/hand.py ``Hands``);
- ``head``: the pan and tilt targets (rad), which the head's servos ramp to;
- ``disturb``: a disturbance of the kitchen, not a robot action (a person moves an object): a
  sequence number, the MuJoCo id of a free body, its shift (dx, dy, dz; m, world) and a turn
  about the world's x axis through its origin (rad). Taken once, when the sequence number
  changes (velma/world/hardware.py ``displace``).

The whole kitchen (the scene block of the link) is ``1 + nq`` values: the world's time, then
MuJoCo's ``qpos``.
"""

from __future__ import annotations

from dataclasses import dataclass

from velma.control.hand import HAND_WIDTH
from velma.control.joints import EXPECTED_NV

N_JOINTS = EXPECTED_NV
"""Velma's joints in the link (Pinocchio's nv: torso 1, arms 2 × 7, head 2, hands 2 × 8)."""
N_SIDES = 2
TOUCH_SLOTS = 4
"""Bodies a hand's tactile summary names at most (the most touched first)."""
SELF_SLOTS = 8
"""Pairs of the robot's own geoms touching each other that one scan reports at most."""
HAND_OP = 4
"""Values per side of a hand command: sequence number, operation, proximal, spread."""
HAND_MOVE, HAND_KEEP = 1.0, 2.0
"""The operations of a hand command (``COMMAND`` ``hand``)."""


@dataclass(frozen=True)
class Block:
    """Named slices of a float64 vector: ``fields`` maps a name to (offset, length)."""

    fields: dict[str, tuple[int, int]]

    @property
    def size(self) -> int:
        return max(offset + length for offset, length in self.fields.values())

    def slice(self, name: str) -> slice:
        """The slice of field ``name``. Raises KeyError for an unknown name."""
        offset, length = self.fields[name]
        return slice(offset, offset + length)


def _block(*parts: tuple[str, int]) -> Block:
    fields, at = {}, 0
    for name, length in parts:
        fields[name] = (at, length)
        at += length
    return Block(fields)


MEASURED = _block(
    ("time", 1),
    ("q", N_JOINTS),
    ("v", N_JOINTS),
    ("ft", 6 * N_SIDES),
    ("touch", 2 * TOUCH_SLOTS * N_SIDES),
    ("holding", 1),
    ("hand", HAND_WIDTH * N_SIDES),
    ("hand_seq", N_SIDES),
    ("self_touch", 2 * SELF_SLOTS),
    ("head", 2),
    ("disturb_seq", 1),
)
COMMAND = _block(("tau", 7 * N_SIDES + 1), ("hand", HAND_OP * N_SIDES), ("head", 2), ("disturb", 6))
