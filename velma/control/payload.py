"""What a hand holds, as the impedance law compensates it: the load data of a KUKA LWR4+ tool.

The real arm's controller takes the tool's mass and centre of mass ("load data") and adds their
weight to its gravity model; Velma's controller does the same for what a BarrettHand holds
(velma/model/README.md "Payload"). A :class:`Payload` is that data for one arm: ``mass`` (kg)
and ``com`` (m, (3,), in the grip frame ``{side}_HandGripLink``). Its joint torque
(:func:`payload_torque`) is the weight's wrench at the grip frame carried to the joints:

    τ_load = −Jᵀ (f, c × f),  f = m Rᵀ g

with ``J`` (6 × 7) the grip frame's Jacobian in that frame (Pinocchio ``LOCAL``), ``R`` the grip
frame's rotation (world), ``g`` the model's gravity (m/s², world; (0, 0, −9.81)) and ``c`` the
centre of mass: the torque that holds the load still, as ``g(q)`` holds the arm. Only its
weight is compensated: the load's inertia in motion is not (its accelerations in the kitchen's
motions are below 1 m/s², under a tenth of g).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from velma.control.joints import Array

MAX_PAYLOAD_KG = 5.0
"""The heaviest load a hand may be given (kg): above the BarrettHand BH8-282's payload (2 kg
per finger); a larger mass is an error (a wrong prior or estimate), not a load."""


@dataclass(frozen=True)
class Payload:
    """Load data of one arm: ``mass`` (kg, 0 ≤ mass ≤ :data:`MAX_PAYLOAD_KG`) and ``com``
    (m, (3,), the centre of mass in the grip frame). Raises ValueError for a mass outside that
    range or a centre of mass that is not three finite numbers."""

    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    source: str = field(default="none", compare=False)
    """Where the data came from: ``none``, ``prior`` (the object's mass as the knowledge base
    gives it) or ``estimate`` (the wrist F/T identification, velma/control/payload_estimate.py)."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.mass <= MAX_PAYLOAD_KG:
            raise ValueError(f"a payload's mass must be within 0–{MAX_PAYLOAD_KG:g} kg, got {self.mass!r}")
        if len(self.com) != 3 or not all(np.isfinite(self.com)):
            raise ValueError(f"a payload's centre of mass must be three finite numbers (m), got {self.com!r}")

    @property
    def empty(self) -> bool:
        """Nothing to compensate (mass 0)."""
        return self.mass == 0.0


NO_PAYLOAD = Payload()
"""An empty hand."""


def payload_wrench(payload: Payload, rotation: Array, gravity: Array) -> Array:
    """The wrench (6,) the arm exerts at the grip frame to hold ``payload`` still, in the grip
    frame: −(f, c × f) with f = m Rᵀ g (N, N·m). ``rotation`` (3, 3): the grip frame's
    rotation (world); ``gravity`` (3,) m/s², world."""
    f = payload.mass * (rotation.T @ gravity)
    out: Array = -np.concatenate([f, np.cross(payload.com, f)])
    return out


def payload_torque(payload: Payload, jacobian: Array, rotation: Array, gravity: Array) -> Array:
    """τ_load (7,) N·m (module docstring): ``jacobian`` (6, 7) the grip frame's (``LOCAL``),
    ``rotation`` (3, 3) its rotation (world), ``gravity`` (3,) m/s² (world)."""
    out: Array = jacobian.T @ payload_wrench(payload, rotation, gravity)
    return out
