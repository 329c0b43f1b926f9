"""L_SD: sensor data from ag_ex (C5): what the robot perceives of the scene.

Perception is simulated: object poses are read from the physics with no noise, and the
content of a container is counted from the particles inside its volume (a named
simplification; a real robot would localise objects from the head camera).
"""

from __future__ import annotations

import msgspec

from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.common import Pose


class ObjectObservation(msgspec.Struct, frozen=True, kw_only=True):
    """One perceived object: ``name`` (as in the scene), its ``pose`` (world) and, for
    containers, ``particles_inside`` (count of content particles within it)."""

    name: str
    pose: Pose
    particles_inside: int | None = None


class Observation(msgspec.Struct, frozen=True, tag="observation", kw_only=True):
    """A snapshot at simulation time ``stamp`` (s); ``total_particles`` in the scene."""

    stamp: float
    objects: tuple[ObjectObservation, ...]
    total_particles: int = 0


L_SD = register(Language("L_SD", "O_RoCo", (Observation,)))
