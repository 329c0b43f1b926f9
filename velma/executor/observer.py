"""The camera's Observation: render the head's Kinect of a captured world state
(velma/executor/capture.py) and localise the requested objects in it (velma/perception/),
outside the 1 kHz loop (``ResultDelivery``, velma/executor/delivery.py, runs it).

What the agents get (L_SD, shared/fipa_codec/languages/l_sd.py):

- a movable object (jar, bowl, cup) seen: its estimated pose (bottom centre; yaw 0 and
  ``yaw_observable`` False for these rotationally symmetric containers), ``position_sigma``
  = max(√trace of the localiser's 3 × 3 position covariance, ``POSITION_SIGMA_FLOOR``) and,
  for a container, the content estimate: through the jar's glass the fill level
  (velma/perception/content.py ``estimate_content``), in an open opaque bowl or cup the
  spheres counted (``count_spheres``: those seen, and those the bowl's near wall hides
  inferred from the gaps of the ring they form along the wall), at most the content there is
  (``total_particles`` less ``particles_outside``: the camera's inference behind the wall can
  count more); ``particles_inferred`` says how many of them were inferred, not seen;
- ``particles_outside`` when a movable object (each is a container) was asked for: the content
  spheres seen resting on a support outside every container (velma/perception/spill.py:
  spilled in view). When some are seen outside the containers asked for, all movable objects
  are localised (a content sphere in another container in view is in no spill), those not
  asked for left out of the Observation;
- a requested object not seen (out of view, occluded, fit rejected, unknown name): its name in
  ``unseen``;
- furniture (table, cabinet): fixed bodies of the kitchen, so their poses are the map's facts
  (the model's body poses, not the simulation state) with ``position_sigma`` None — a named
  simplification: a real robot would also localise against its map;
- ``grips``: each hand's grip frame from the joint angles (velma/executor/proprioception.py);
- ``total_particles``: the number of content spheres the scene description states (its content
  bodies, ``N_PARTICLES`` = 18 in the kitchen), a task fact, not a measurement.

A watch frame (``WorldCapture.watch``: velma/executor/watch.py, ag_ex's watch) is observed in
a cheaper mode: one Kinect frame (``WATCH_FRAMES``, not ``FRAMES_AVERAGED``) of ``WATCH_SIZE``
px by a renderer of its own (made at the first watch frame), the requested movable objects
localised, no content count (``particles_inside`` None) and no spill count
(``particles_outside`` None): a watch tells where things are and how they stand, an Observe
also what they hold (docs/bench/observe.md measures both).

``ROCO_PERCEPTION`` (velma/executor/capture.py ``perception_mode``) chooses ``camera`` or
``truth`` (velma/executor/ground_truth.py, in the loop); unset: ``DEFAULT_PERCEPTION``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import msgspec
import mujoco
import numpy as np

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from velma.executor.capture import WorldCapture
from velma.executor.proprioception import GripFrames
from velma.model.scene import PARTICLE_PREFIX, PARTICLE_RADIUS
from velma.perception.content import ContentEstimate, SphereCount, count_spheres, estimate_content
from velma.perception.kinect import HeadKinect
from velma.perception.localise import Localiser, ObjectEstimate
from velma.perception.objects import ObjectModel, object_model
from velma.perception.segment import support_heights
from velma.perception.spill import Spill, count_outside

MOVABLE = ("jar", "bowl", "cup")
"""The objects the camera localises (free bodies with a model, velma/perception/objects.py)."""
FURNITURE = ("table", "cabinet")
"""Fixed bodies: poses from the kitchen's map (module docstring)."""
POSITION_SIGMA_FLOOR = 0.001
"""Least ``position_sigma`` (m) of a seen object. ICP's own σ (0.1–0.4 mm) is smaller than the
true error, which docs/bench/perception.md measured over 20 pose seeds: the RMS of the 3-D
errors of the jar's 20 fits is 0.95 mm (p50 0.71, p95 1.69); the floor is that, rounded up."""
CAMERA_SIZE = (640, 480)
"""Frame (px) rendered per Observe: the Kinect's own. 320 × 240 localises as well and takes
≈ 0.3 s an Observe instead of ≈ 0.3–1 s, but counted 13–14 of ≈ 16 visible spheres in the
bowl where 640 × 480 counts 15–16 (docs/bench/observe.md)."""
FRAMES_AVERAGED = 5
"""Depth frames averaged per Observe (the scene is static while the robot observes: 5 frames
are 0.17 s of the Kinect's 30 Hz; velma/perception/kinect.py ``HeadKinect.capture``)."""
WATCH_FRAMES = 1
"""Depth frames per watch frame (module docstring): the scene may be moving, and one frame is
what a streaming Kinect gives every 1/30 s."""
WATCH_SIZE = (320, 240)
"""Frame (px) rendered per watch frame: a quarter of the pixels, so a quarter of the software
renderer's work; it localises as well as 640 × 480 (``CAMERA_SIZE``), and a watch counts no
content (docs/bench/observe.md)."""


@dataclass(frozen=True)
class Seen:
    """What one Observe saw besides its Observation (for the perception log): per object the
    localiser's estimate and, for containers, the content estimate."""

    estimates: dict[str, ObjectEstimate]
    content: dict[str, ContentEstimate | SphereCount]
    outside: Spill | None = None
    """The content seen outside every container (None when no movable object was asked for)."""


def _inside(guess: ContentEstimate | SphereCount | None, conserved: int) -> int | None:
    """The spheres estimated in a container (``guess``'s count, at most ``conserved``: the
    content not seen outside every container); None without an estimate."""
    return max(0, min(guess.count, conserved)) if guess is not None else None


def _inferred(guess: ContentEstimate | SphereCount | None, conserved: int) -> int | None:
    """How many of :func:`_inside`'s spheres were inferred, not seen: a ``SphereCount``'s
    hidden ones, less what the cap on ``conserved`` took (the cap takes the inferred first,
    the seen ones being in view); None for an estimate not split so (a fill level)."""
    if not isinstance(guess, SphereCount):
        return None
    seen = max(0, min(guess.visible, conserved))
    return max(0, min(guess.count, conserved)) - seen


def _located(e: ObjectEstimate) -> bool:
    """Whether the localiser saw the object and gave its pose."""
    return e.seen and e.position is not None and e.quaternion is not None


def _seen(name: str, e: ObjectEstimate) -> ObjectObservation:
    """The observation of object ``name`` that estimate ``e`` (:func:`_located`) gives: its pose
    and the position's σ (floored at ``POSITION_SIGMA_FLOOR``), no content."""
    assert e.position is not None and e.quaternion is not None
    p, q = e.position, e.quaternion
    return ObjectObservation(
        name=name,
        pose=Pose(
            position=(float(p[0]), float(p[1]), float(p[2])),
            orientation=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
        ),
        position_sigma=max(e.sigma_position, POSITION_SIGMA_FLOOR)
        if math.isfinite(e.sigma_position)
        else None,
        yaw_observable=e.yaw_observable,
    )


class CameraObserver:
    """Observes captured world states of ``model`` (the loop's kitchen, same seeds) with the
    head Kinect at ``size`` px; Kinect noise drawn from a generator seeded with ``seed``.
    Builds the object models and ICP targets at construction (≈ 0.3 s). Its renderer's GL
    context belongs to the thread that first calls ``observe``: use one thread."""

    def __init__(self, model: mujoco.MjModel, size: tuple[int, int] = CAMERA_SIZE, seed: int = 0) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.kinect = HeadKinect(model, size[0], size[1])
        self.watch_kinect: HeadKinect | None = None
        """The watch frames' camera (``WATCH_SIZE``), made at the first one."""
        self.models: dict[str, ObjectModel] = {n: object_model(model, n) for n in MOVABLE}
        self.localiser = Localiser(self.models.values())
        self.rng = np.random.default_rng(seed)
        particles = [b for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX)]
        self.total_particles = len(particles)
        self.content_rgba = (
            model.geom_rgba[model.geom(f"{PARTICLE_PREFIX}0_geom").id].copy() if particles else np.ones(4)
        )
        self.map = {n: self._map_pose(n) for n in FURNITURE}
        self.grips = GripFrames(model)

    def _map_pose(self, name: str) -> Pose:
        """The pose of fixed body ``name`` as the model places it (a map fact). Raises
        ``ValueError`` if it is not fixed to the world."""
        b = self.model.body(name)
        if int(self.model.body_jntnum[b.id]) != 0 or int(self.model.body_parentid[b.id]) != 0:
            raise ValueError(f"{name} is not a fixed body of the world")
        p, q = self.model.body_pos[b.id], self.model.body_quat[b.id]
        return Pose(position=(float(p[0]), float(p[1]), float(p[2])), orientation=tuple(float(x) for x in q))  # type: ignore[arg-type]

    def load(self, capture: WorldCapture) -> mujoco.MjData:
        """This observer's MjData set to ``capture``'s state with its kinematics computed.
        Raises ``ValueError`` for a ``qpos`` of another size."""
        qpos = capture.positions()
        if qpos.shape != (self.model.nq,):
            raise ValueError(f"qpos has {qpos.size} values, the model needs {self.model.nq}")
        d = self.data
        d.qpos[:] = qpos
        d.time = capture.stamp
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        mujoco.mj_camlight(self.model, d)
        return d

    def observe(self, capture: WorldCapture) -> tuple[Observation, Seen]:
        """The Observation of ``capture``'s objects (all movable ones and the furniture when
        empty) as the head camera sees them (module docstring), and the details; a watch frame
        (``capture.watch``) in the watch mode (:meth:`watch`)."""
        if capture.watch:
            return self.watch(capture)
        names = capture.objects or (*MOVABLE, *FURNITURE)
        data = self.load(capture)
        wanted = [n for n in names if n in self.models]
        estimates: dict[str, ObjectEstimate] = {}
        content: dict[str, ContentEstimate | SphereCount] = {}
        objects: list[ObjectObservation] = []
        outside: Spill | None = None
        if wanted:
            frame = self.kinect.capture(data, self.rng, FRAMES_AVERAGED)
            points, colours, _ = frame.cloud()
            supports = support_heights(points)
            found = self.localiser.localise(points, colours, frame.position, wanted, supports)
            outside = spill = self._outside(points, colours, supports, found)
            if spill.count and len(wanted) < len(MOVABLE):
                # content outside the containers asked for: it may lie in another one in view
                found = self.localiser.localise(points, colours, frame.position, MOVABLE, supports)
                outside = spill = self._outside(points, colours, supports, found)
            estimates = {n: found[n] for n in wanted}
            conserved = self.total_particles - spill.count
            for n in wanted:
                e = estimates[n]
                if not _located(e):
                    continue
                model = self.models[n]
                guess: ContentEstimate | SphereCount | None
                if model.transparent:
                    guess = estimate_content(
                        e, model, points, colours, frame.position, self.content_rgba, PARTICLE_RADIUS
                    )
                else:
                    k = frame.intrinsics
                    guess = count_spheres(
                        e, model, points, colours, frame.depth, frame.rgb, frame.position, frame.rotation,
                        k.fx, k.cx, k.cy, self.content_rgba, PARTICLE_RADIUS,
                    )  # fmt: skip
                if guess is not None:
                    content[n] = guess
                objects.append(
                    msgspec.structs.replace(
                        _seen(n, e),
                        particles_inside=_inside(guess, conserved),
                        particles_inferred=_inferred(guess, conserved),
                    )
                )
        obs = self._observation(capture, names, objects, data, outside)
        return obs, Seen(estimates=estimates, content=content, outside=outside)

    def watch(self, capture: WorldCapture) -> tuple[Observation, Seen]:
        """The watch mode's Observation of ``capture`` (module docstring): one frame, the
        requested movable objects (all when empty) localised, the furniture from the map, no
        content and no spill count."""
        names = capture.objects or (*MOVABLE, *FURNITURE)
        data = self.load(capture)
        estimates = self._localise_once([n for n in names if n in self.models], data)
        objects = [_seen(n, e) for n, e in estimates.items() if _located(e)]
        return self._observation(capture, names, objects, data, None), Seen(estimates=estimates, content={})

    def _localise_once(self, wanted: list[str], data: mujoco.MjData) -> dict[str, ObjectEstimate]:
        """The estimates of the objects ``wanted`` in one Kinect frame of ``data``."""
        if not wanted:
            return {}
        if self.watch_kinect is None:
            self.watch_kinect = HeadKinect(self.model, *WATCH_SIZE)
        frame = self.watch_kinect.capture(data, self.rng, WATCH_FRAMES)
        points, colours, _ = frame.cloud()
        found = self.localiser.localise(points, colours, frame.position, wanted, support_heights(points))
        return {n: found[n] for n in wanted}

    def _observation(
        self,
        capture: WorldCapture,
        names: tuple[str, ...],
        objects: list[ObjectObservation],
        data: mujoco.MjData,
        outside: Spill | None,
    ) -> Observation:
        """The Observation of ``capture``: ``objects`` seen, the furniture of ``names`` from the
        map, the rest of ``names`` unseen, the hands' grips of ``data``, the spill seen."""
        objects = objects + [ObjectObservation(name=n, pose=self.map[n]) for n in names if n in self.map]
        seen = {o.name for o in objects}
        return Observation(
            stamp=capture.stamp,
            objects=tuple(objects),
            total_particles=self.total_particles,
            unseen=tuple(n for n in names if n not in seen),
            particles_outside=outside.count if outside is not None else None,
            grips=self.grips.observe(data),
        )

    def _outside(
        self, points: np.ndarray, colours: np.ndarray, supports: list[float], found: dict[str, ObjectEstimate]
    ) -> Spill:
        """The content seen outside the containers of ``found`` (velma/perception/spill.py);
        every movable object is a container."""
        containers = [(e, self.models[n]) for n, e in found.items()]
        return count_outside(points, colours, supports, containers, self.content_rgba, PARTICLE_RADIUS)

    def close(self) -> None:
        """Free the renderers (from the thread that observed)."""
        self.kinect.close()
        if self.watch_kinect is not None:
            self.watch_kinect.close()
