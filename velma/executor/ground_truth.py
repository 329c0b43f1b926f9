"""Ground truth of the kitchen, read from the physics: the true object poses and content
counts, for tests and for the perception log (ag_ex_perception.jsonl), never for the agents
when the camera perceives (the default; velma/executor/observer.py).

Object poses are the MuJoCo body poses, exactly; a container's ``particles_inside`` is the
number of ``jar_content_*`` spheres whose centre lies inside the container's inner volume (the
cylinder site ``{container}_inner``: radius, half height, in the container frame).

It serves the agents only with ``ROCO_PERCEPTION=truth`` (velma/executor/capture.py
``perception_mode``; the default is the camera) — not perception.

This is the one module of the executor that reads objects' body poses for observations
(tests/architecture/test_perception_sources.py checks it).
"""

from __future__ import annotations

import mujoco
import numpy as np

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from velma.executor.proprioception import GripFrames
from velma.model.scene import PARTICLE_PREFIX

KNOWN_OBJECTS = ("jar", "bowl", "cup", "table", "cabinet")
CONTAINERS = ("jar", "bowl", "cup")
"""Objects with an inner volume (site ``{name}_inner``): their observation counts the content
spheres inside (the cup holds none at the start, but content poured into it would count)."""


class GroundTruth:
    """Reads object poses and content counts from a kitchen model's state (module docstring)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.body = {n: model.body(n).id for n in KNOWN_OBJECTS}
        self.particle_bodies = np.array(
            [b for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX)], dtype=np.int64
        )
        self.inner_site = {c: model.site(f"{c}_inner").id for c in CONTAINERS}
        self.grips = GripFrames(model)

    def pose(self, data: mujoco.MjData, name: str) -> Pose:
        """World pose of body ``name`` (position m, quaternion w, x, y, z) in ``data`` (its
        kinematics computed). Raises KeyError for an unknown object."""
        b = self.body[name]
        p = data.xpos[b]
        q = data.xquat[b]
        return Pose(
            position=(float(p[0]), float(p[1]), float(p[2])),
            orientation=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
        )

    def particles_inside(self, data: mujoco.MjData, container: str) -> int:
        """Number of content spheres whose centre is inside ``container``'s inner cylinder."""
        if self.particle_bodies.size == 0:
            return 0
        s = self.inner_site[container]
        radius, half = self.model.site_size[s][0], self.model.site_size[s][1]
        rot = data.site_xmat[s].reshape(3, 3)
        local = (data.xpos[self.particle_bodies] - data.site_xpos[s]) @ rot
        inside = (np.hypot(local[:, 0], local[:, 1]) <= radius) & (np.abs(local[:, 2]) <= half)
        return int(np.count_nonzero(inside))

    def observe(self, data: mujoco.MjData, objects: tuple[str, ...] = ()) -> Observation:
        """The true Observation of ``objects`` (all known objects when empty); unknown names
        are listed as ``unseen``. ``position_sigma`` is None: these are not estimates."""
        names = objects or KNOWN_OBJECTS
        out = []
        for name in names:
            if name not in self.body:
                continue
            inside = self.particles_inside(data, name) if name in CONTAINERS else None
            out.append(ObjectObservation(name=name, pose=self.pose(data, name), particles_inside=inside))
        outside = None
        if any(n in CONTAINERS for n in names):
            outside = int(self.particle_bodies.size) - sum(self.particles_inside(data, c) for c in CONTAINERS)
        return Observation(
            stamp=float(data.time),
            objects=tuple(out),
            total_particles=int(self.particle_bodies.size),
            unseen=tuple(n for n in names if n not in self.body),
            particles_outside=outside,
            grips=self.grips.observe(data),
        )
