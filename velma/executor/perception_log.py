"""Each camera Observation beside the truth, for the run's report (never for the agents):
one record per requested object, written by ag_ex as a JSON line to
``<ROCO_RUN_DIR>/ag_ex_perception.jsonl`` (services/agents/executor/agent.py).

A record: ``sim_time`` (s), ``object``, ``seen``, ``estimate`` (position, m, or None),
``truth`` (position, m, from velma/executor/ground_truth.py), ``error_mm`` (distance, or
None), ``sigma_mm`` (the reported 1-σ), ``content`` (estimate) and ``content_truth`` (spheres
inside, containers only), ``visible``, ``hidden`` and ``floor_visible`` (open containers:
spheres seen, spheres inferred behind the near wall, share of the floor in view), ``reason``
(why not seen), ``observe_ms`` (the render and localisation's wall time), and, with the
Observation's ``particles_outside``, ``outside`` (content seen outside every container,
velma/perception/spill.py) beside ``outside_truth`` (spheres in no container).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco

from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.ground_truth import CONTAINERS, GroundTruth
from velma.executor.observer import Seen
from velma.perception.content import SphereCount

Record = dict[str, Any]


def records(obs: Observation, seen: Seen, truth: GroundTruth, data: mujoco.MjData, ms: float) -> list[Record]:
    """One record per object the localiser was asked for in ``obs`` (seen or not), the truth
    read from ``data`` (the captured state, kinematics computed)."""
    by_name = {o.name: o for o in obs.objects}
    outside_truth = (
        None
        if obs.particles_outside is None
        else obs.total_particles - sum(truth.particles_inside(data, c) for c in CONTAINERS)
    )
    out: list[Record] = []
    for name, e in seen.estimates.items():
        o = by_name.get(name)
        true = truth.pose(data, name).position
        est = o.pose.position if o is not None else None
        c = seen.content.get(name)
        out.append(
            {
                "sim_time": obs.stamp,
                "object": name,
                "seen": o is not None,
                "estimate": list(est) if est is not None else None,
                "truth": list(true),
                "error_mm": round(1e3 * math.dist(est, true), 3) if est is not None else None,
                "sigma_mm": round(1e3 * o.position_sigma, 3) if o is not None and o.position_sigma else None,
                "content": o.particles_inside if o is not None else None,
                "content_truth": truth.particles_inside(data, name) if name in CONTAINERS else None,
                "visible": c.visible if isinstance(c, SphereCount) else None,
                "hidden": c.hidden if isinstance(c, SphereCount) else None,
                "floor_visible": round(c.floor_visible, 3) if isinstance(c, SphereCount) else None,
                "reason": e.reason or None,
                "observe_ms": round(ms, 1),
                "outside": obs.particles_outside,
                "outside_truth": outside_truth,
            }
        )
    return out
