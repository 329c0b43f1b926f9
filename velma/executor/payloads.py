"""What each hand holds, given to the impedance law as its load data and kept up to date from
the wrist F/T sensor (velma/control/payload.py, payload_estimate.py; velma/model/README.md
"Payload").

A grasp that holds an object (``GraspPrimitive``) calls :meth:`HeldLoads.grasped` with the
object's mass as the knowledge base gives it (L_EX ``Grasp.load``; None: not known): the law
compensates that prior at once, with the object's centre of mass where the grasp found it (in
the grip frame: the kitchen's pose of the object's body at that moment, as perceived). Every
:data:`READING_CYCLES` cycles the identification takes a reading, and the law gets the new
estimate. A hand that holds something the runtime did not see grasped (a restart attached to a
world whose hand holds an object, a checkpoint restored) starts from no prior, already lifted;
a hand that lets go (a release, the object lost) holds nothing from the next cycle.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import mujoco
import numpy as np
import pinocchio as pin

from velma.control.impedance import VelmaController
from velma.control.joints import SIDES, Array
from velma.control.payload import NO_PAYLOAD, Payload
from velma.control.payload_estimate import PERIOD_S, PayloadEstimate
from velma.world.hardware import DT

READING_CYCLES = round(PERIOD_S / DT)
"""Cycles between two readings of the identification (10: 100 Hz)."""
SOURCES = ("none", "prior", "estimate")
"""``Payload.source`` values, in the order a checkpoint numbers them."""
STATE_SIZE = 13
"""Numbers of one hand's :meth:`HeldLoads.pack`."""
UNKNOWN_Z = -1e6
"""m: the grasp height of a hand seen holding without its grasp (already lifted)."""


class HeldLoads:
    """The load data of both hands (module docstring). ``model``: the kitchen's; ``ctrl``: the
    law whose ``payload`` this sets; ``ft_site``: each wrist sensor's site id (its body's
    subtree is the hand the sensor carries)."""

    def __init__(self, model: mujoco.MjModel, ctrl: VelmaController, ft_site: Mapping[str, int]) -> None:
        self._ctrl = ctrl
        self.enabled = True
        """False: nothing is compensated and nothing identified (for comparisons: the law as
        it was without load data); set before the hand grasps."""
        self.hand_mass = {s: float(model.body_subtreemass[model.site_bodyid[ft_site[s]]]) for s in SIDES}
        """kg the wrist sensor carries of the hand itself (palm and fingers, velma.xml)."""
        self.gravity = float(np.linalg.norm(model.opt.gravity))
        self.estimate: dict[str, PayloadEstimate | None] = {s: None for s in SIDES}
        """Each hand's identification, None: it holds nothing."""
        self._body: dict[str, int | None] = {s: None for s in SIDES}
        self._com: dict[str, tuple[float, float, float]] = {s: (0.0, 0.0, 0.0) for s in SIDES}
        self._last_p: dict[str, Array] = {s: np.zeros(3) for s in SIDES}

    def grasped(self, side: str, body: int, grip: pin.SE3, com: Array, prior: float | None) -> None:
        """``side``'s hand holds ``body`` (a MuJoCo body id), its grip frame at ``grip`` and
        the object's centre of mass at ``com`` (m, world); ``prior``: the object's mass (kg) as
        known, or None. Raises ValueError for a prior outside 0 … ``MAX_PAYLOAD_KG``."""
        if not self.enabled:
            return
        com = grip.rotation.T @ (com - grip.translation)
        self._com[side] = (float(com[0]), float(com[1]), float(com[2]))
        load = Payload(prior, self._com[side], source="prior") if prior is not None else NO_PAYLOAD
        self._begin(side, body, grip, prior, float(grip.translation[2]))
        self._ctrl.payload[side] = load

    def _begin(self, side: str, body: int, grip: pin.SE3, prior: float | None, grasp_z: float) -> None:
        self._body[side] = body
        self._last_p[side] = grip.translation.copy()
        self.estimate[side] = PayloadEstimate(self.hand_mass[side], self.gravity, grasp_z, prior)

    def follow(
        self,
        held: Mapping[str, int | None],
        cycle: int,
        grip: Callable[[str], pin.SE3],
        force: Callable[[str], Array],
    ) -> None:
        """Once per cycle, after the physics step: the hands' loads follow ``held`` (body id
        per side, None: nothing), and every :data:`READING_CYCLES` cycles (``cycle``) each
        holding hand's identification takes a reading of ``force(side)`` (N, world: the force
        the arm exerts on the hand) at ``grip(side)``."""
        if not self.enabled:
            return
        reading = cycle % READING_CYCLES == 0
        for side in SIDES:
            body = held[side]
            if body != self._body[side]:
                if body is None:
                    self._body[side] = self.estimate[side] = None
                    self._ctrl.payload[side] = NO_PAYLOAD
                    continue
                pose = grip(side)  # held without a grasp seen here: no prior, already lifted
                self._com[side] = (0.0, 0.0, 0.0)
                self._begin(side, body, pose, None, UNKNOWN_Z)
            estimate = self.estimate[side]
            if estimate is None or not reading:
                continue
            p = grip(side).translation
            speed = float(np.linalg.norm(p - self._last_p[side])) / PERIOD_S
            self._last_p[side] = p.copy()
            if estimate.reading(float(force(side)[2]), float(p[2]), speed):
                self._ctrl.payload[side] = Payload(estimate.mass, self._com[side], source="estimate")

    def pack(self, side: str) -> tuple[float, ...]:
        """``side``'s load data and identification as :data:`STATE_SIZE` finite numbers (a
        checkpoint's, velma/executor/checkpoint.py): mass, the centre of mass found at the
        grasp (3), source (index in :data:`SOURCES`), prior (−1: none), estimate, readings,
        lifted (0/1), grasp height (m; −1e6: unknown, lifted), the grip frame's position at the
        last reading (m, 3)."""
        load, est = self._ctrl.payload[side], self.estimate[side]
        head = (load.mass, *self._com[side], float(SOURCES.index(load.source)))
        if est is None:
            return (*head, -1.0, *([0.0] * (STATE_SIZE - len(head) - 1)))
        prior = -1.0 if est.prior is None else est.prior
        grasp_z = max(est.grasp_z, UNKNOWN_Z)
        return (*head, prior, est.mass, float(est.readings), float(est.lifted), grasp_z, *self._last_p[side])

    def unpack(self, side: str, values: Sequence[float], body: int | None) -> None:
        """Put back what :meth:`pack` gave, ``side``'s hand holding ``body`` (None: nothing).
        Raises ValueError for numbers no load can have."""
        mass, cx, cy, cz, source, prior, est_mass, readings, lifted, grasp_z, *last = (
            float(x) for x in values
        )
        if not self.enabled:
            self._body[side], self.estimate[side], self._ctrl.payload[side] = body, None, NO_PAYLOAD
            return
        self._com[side] = (cx, cy, cz)
        self._ctrl.payload[side] = Payload(mass, self._com[side], source=SOURCES[int(source)])
        self._body[side] = body
        self.estimate[side] = None
        if body is not None:
            est = PayloadEstimate(self.hand_mass[side], self.gravity, grasp_z, None if prior < 0 else prior)
            est.mass, est.readings, est.lifted = est_mass, int(readings), lifted != 0.0
            self._last_p[side] = np.array(last)
            self.estimate[side] = est

    def verdict(self, side: str) -> str | None:
        """One line when ``side``'s settled estimate contradicts its prior (else None)."""
        estimate = self.estimate[side]
        return None if estimate is None else estimate.verdict()
