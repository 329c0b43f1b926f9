"""What crosses the robot link each cycle (velma/world/link.py), number by number: the
robot's measured state from the world, the command back from the controller.

Joints are in Pinocchio's velocity order (``velma.control.robot_model.RobotModel``: the
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
- ``holding``: 1 while the world's safety layer holds the robot (no command came in time), else 0.

Command (``COMMAND``):

- ``tau``: per side the 7 arm joint torques (N·m), then the torso's;
- ``hand``: per side the spread target and the proximal joints' target (rad; NaN: keep the
  target), which the hand's own servos ramp to (velma/control/hand.py ``Hands``);
- ``head``: the pan and tilt targets (rad), which the head's servos ramp to.
"""

from __future__ import annotations

from dataclasses import dataclass

N_JOINTS = 33
"""Velma's joints in the link (Pinocchio's nv: torso 1, arms 2 × 7, head 2, hands 2 × 8)."""
N_SIDES = 2
TOUCH_SLOTS = 4
"""Bodies a hand's tactile summary names at most (the most touched first)."""


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
)
COMMAND = _block(("tau", 7 * N_SIDES + 1), ("hand", 2 * N_SIDES), ("head", 2))
