"""The held object's mass identified from the wrist force/torque sensor, as Velma's
controller can do it with the 6-axis F/T sensor in each wrist (velma/model/README.md "Payload").

At rest, the force the arm exerts on its hand through the sensor carries the weight of the hand
(everything distal to the sensor: palm and fingers, mass ``hand_mass`` from the robot model)
and of what it holds: in world axes, f_z = (m_hand + m) g. Hence

    m̂ = f_z / g − m_hand

taken only while the grip frame is at rest (its speed below :data:`REST_SPEED` m/s: the hand's
own acceleration stays out of the reading) and only once the object is lifted (the grip frame
:data:`LIFTED_M` above where it grasped: before that the surface under the object carries part
of its weight). The estimate is filtered (first order, time constant :data:`TIME_CONSTANT_S`)
from the prior, the object's mass as the knowledge base gives it (L_EX ``Grasp.load``), or from
0 kg without one; it follows the content as it leaves the jar, and falls when a surface takes
the object's weight again (a set-down). The centre of mass is not identified: it stays where
the grasp found the object's (velma/executor/runtime.py ``Runtime.grasped``).
"""

from __future__ import annotations

from dataclasses import dataclass

from velma.control.payload import MAX_PAYLOAD_KG

REST_SPEED = 0.05
"""m/s: the grip frame's speed below which a reading counts (a min-jerk motion's ends, a
pour's slow tilt; at 0.05 m/s the hand's acceleration in the kitchen's motions is < 0.1 m/s²,
1 % of g)."""
LIFTED_M = 0.02
"""m the grip frame must rise above its height at the grasp before readings count (every
grasp's lift is ≥ 0.04 m: L_WM ``GraspAffordance.lift``)."""
TIME_CONSTANT_S = 0.3
"""s: the estimate's filter (readings at rest every :data:`PERIOD_S`)."""
PERIOD_S = 0.01
"""s between two readings (the loop takes one every 10 cycles)."""
DISAGREE_FRACTION = 0.25
"""A prior that differs from the settled estimate by more than this fraction of the larger
(and by more than :data:`DISAGREE_MIN_KG`) is wrong: :meth:`PayloadEstimate.verdict` says so."""
DISAGREE_MIN_KG = 0.03
"""kg below which a difference between prior and estimate is noise (the sensor's, a sphere
of the content)."""
SETTLED_READINGS = 100
"""Readings at rest (1 s at :data:`PERIOD_S`) after which the estimate is settled."""


@dataclass
class PayloadEstimate:
    """The mass (kg) one hand holds, from its F/T readings (module docstring).

    ``hand_mass`` (kg): what the sensor carries of the hand itself; ``gravity`` (m/s²) the
    model's acceleration of gravity (its magnitude); ``grasp_z`` (m, world): the grip frame's
    height at the grasp; ``prior`` (kg, or None: none known): where the estimate starts. Call
    :meth:`reading` every :data:`PERIOD_S`."""

    hand_mass: float
    gravity: float
    grasp_z: float
    prior: float | None = None
    mass: float = 0.0
    """The current estimate (kg, 0 … ``MAX_PAYLOAD_KG``)."""
    readings: int = 0
    """Readings taken in (at rest, lifted)."""
    lifted: bool = False

    def __post_init__(self) -> None:
        self.mass = 0.0 if self.prior is None else self.prior

    def reading(self, force_z: float, grip_z: float, speed: float) -> bool:
        """Take one reading: ``force_z`` (N) the vertical force the arm exerts on the hand
        (world +z up), ``grip_z`` (m) the grip frame's height, ``speed`` (m/s) its speed.
        Returns whether the estimate changed."""
        if not self.lifted:
            if grip_z - self.grasp_z < LIFTED_M:
                return False
            self.lifted = True
        if speed >= REST_SPEED:
            return False
        measured = min(max(force_z / self.gravity - self.hand_mass, 0.0), MAX_PAYLOAD_KG)
        self.mass += (measured - self.mass) * (PERIOD_S / TIME_CONSTANT_S)
        self.readings += 1
        return True

    @property
    def settled(self) -> bool:
        """Enough readings at rest for the estimate to stand for the object (≈ 3 time constants)."""
        return self.readings >= SETTLED_READINGS

    def verdict(self) -> str | None:
        """One line when the settled estimate contradicts the prior (a wrong mass in the
        knowledge base, or a different object in the hand), else None."""
        if self.prior is None or not self.settled:
            return None
        apart = abs(self.mass - self.prior)
        if apart <= DISAGREE_MIN_KG or apart <= DISAGREE_FRACTION * max(self.mass, self.prior):
            return None
        used = "the estimate is used"
        return f"payload: prior {self.prior:.3f} kg, wrist F/T estimate {self.mass:.3f} kg ({used})"
