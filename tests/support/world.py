"""The simulated world a run left, for judging it in tests (every scenario is
checked by where the objects ended, not only by what the agents reported): the world
process's final scene observed with the ground truth (services/scenario/chaos.py ``final_world``), and
where a_km's kitchen knowledge places each object."""

from __future__ import annotations

import math
from pathlib import Path

from services.agents.knowledge.world_model import WorldModel
from services.report.world import final_world
from shared.fipa_codec.languages.l_hc import CONTENT_SHARE_REQUIRED
from shared.fipa_codec.languages.l_sd import ObjectObservation
from velma.model.scene import N_PARTICLES, load_kitchen

KITCHEN = WorldModel()
"""a_km's kitchen facts: where each object goes on each piece of furniture."""
START = {n: tuple(load_kitchen(0, 0).body(n).pos) for n in ("jar", "bowl", "cup")}
"""Where the movable objects stand when a run starts (kitchen.xml)."""
UPRIGHT = math.radians(15.0)
FULL = math.ceil(CONTENT_SHARE_REQUIRED * N_PARTICLES)
"""Spheres the bowl holds after a pour that succeeded (≥ 90 % of the content)."""


def world(run_dir: Path) -> dict[str, ObjectObservation]:
    """The simulated world as the run left it (the world's final scene, its ground truth)."""
    obs = final_world(run_dir)
    assert obs is not None, "no final scene of the world in the run folder"
    return {o.name: o for o in obs.objects}


def stands_at(o: ObjectObservation, furniture: str, tolerance: float = 0.03) -> bool:
    """``o`` stands upright within ``tolerance`` m of its place on ``furniture`` (a_km's)."""
    place = KITCHEN.placement(o.name, furniture).positions[0]
    return o.pose.tilt() < UPRIGHT and math.dist(o.pose.position, place) <= tolerance


def untouched(o: ObjectObservation) -> bool:
    """``o`` stands upright within 1 cm of where it stood when the run started."""
    return o.pose.tilt() < UPRIGHT and math.dist(o.pose.position, START[o.name]) <= 0.01
