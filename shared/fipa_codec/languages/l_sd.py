"""L_SD: sensor data from ag_ex (C5): what the robot perceives of the scene.

By default (``ROCO_PERCEPTION`` unset or ``camera``) ag_ex renders the head's
simulated Kinect (RGB-D) of the world as it was when the Observe ran and localises the
requested objects in it (velma/perception/). What is seen carries the estimate's uncertainty
(``position_sigma``); what is not seen (out of view, hidden, fit rejected) is named in
``Observation.unseen``, never guessed. Fixed furniture (table, cabinet) is not measured: its
pose is a fact of the kitchen's map and carries ``position_sigma`` None. With
``ROCO_PERCEPTION=truth`` every pose is read from the physics instead (exact,
``position_sigma`` None, nothing unseen): for tests and comparisons, not perception
(velma/executor/capture.py ``DEFAULT_PERCEPTION``).
"""

from __future__ import annotations

import msgspec

from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.common import Pose


class ObjectObservation(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """One perceived object: ``name`` (as in the scene), its ``pose`` (world) and, for
    containers, ``particles_inside`` (count of content particles estimated within it; None:
    not a container or no estimate) and ``particles_inferred``: how many of those were not
    seen but inferred (spheres the container's near wall hides, counted as full as their
    neighbours, velma/perception/content.py ``count_spheres``); None when the estimate is not
    split so (ground truth, or a fill level seen through glass), so the spheres seen are
    ``particles_inside − (particles_inferred or 0)``.

    ``position_sigma`` (m): 1-σ of the position estimate (√trace of its 3 × 3 covariance, the
    3-D RMS error expected), never below the error scale the perception benchmark measured
    (velma/executor/observer.py ``POSITION_SIGMA_FLOOR``); None when the pose is not a
    measurement (a map fact, or ground truth). ``yaw_observable`` False: the object looks the
    same turned about its vertical axis, so the pose's yaw is arbitrary (0) and means nothing.
    """

    name: str
    pose: Pose
    particles_inside: int | None = None
    particles_inferred: int | None = None
    position_sigma: float | None = None
    yaw_observable: bool = True


class Observation(msgspec.Struct, frozen=True, tag="observation", kw_only=True, omit_defaults=True):
    """A snapshot at simulation time ``stamp`` (s) of the world state the Observe captured.

    ``objects``: what was seen (and furniture, from the map); ``unseen``: the requested
    objects that were not seen (out of view, occluded, fit rejected, unknown), never a guess.
    ``total_particles``: how many content spheres the task's content has in all — not a
    measurement: the count the scene description states (the jar is filled with that many at
    the start; a_km's kitchen knowledge may state it too), so that ``particles_inside /
    total_particles`` is the share of the content a container was seen to hold.
    ``particles_outside``: content particles seen outside every container (spilled on the
    table, a shelf or the floor, in view; with ground truth: all that are in no container);
    None when no container was asked for. The content is conserved, so no container holds
    more than ``total_particles − particles_outside``.
    ``grips``: each hand's grip frame (``{side}_HandGripLink``) where the forward kinematics
    of the joint angles measured at ``stamp`` puts it, named as a_km's grippers
    (``left_gripper``, ``right_gripper``): the robot's proprioception, not the camera's, so it
    holds where a held object is hidden (``position_sigma`` None).
    ``world``: which power-on of the robot (the world process's run: velma/world/) was observed,
    "" when not known (L_EX ``CommandResult.world``)."""

    stamp: float
    objects: tuple[ObjectObservation, ...]
    total_particles: int = 0
    unseen: tuple[str, ...] = ()
    particles_outside: int | None = None
    grips: tuple[ObjectObservation, ...] = ()
    world: str = ""


L_SD = register(Language("L_SD", "O_RoCo", (Observation,)))
