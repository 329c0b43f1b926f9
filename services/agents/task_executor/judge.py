"""a_ta's judgements of the world it observed (every task judged by the world it
left): where the plan's Perceive expects the objects, how certain a position must be for a
grasp, and the content check. Pure functions of the plan's action and ag_ex's L_SD
``Observation`` (shared/fipa_codec/languages/l_sd.py); the reasons are the words the person
reads."""

from __future__ import annotations

import math

from shared.fipa_codec.languages.common import Vec3
from shared.fipa_codec.languages.l_hfsm import CheckContent, Perceive
from shared.fipa_codec.languages.l_sd import Observation


def too_uncertain(action: Perceive, obs: Observation) -> tuple[str, Vec3, float] | None:
    """The first expected object seen with a position less certain than its ``max_sigma``:
    (name, estimated position (m, world), σ m); None when every one is certain enough."""
    seen = {o.name: o for o in obs.objects}
    for e in action.expect:
        o = seen.get(e.object)
        if o is not None and e.max_sigma is not None and (o.position_sigma or 0.0) > e.max_sigma:
            return e.object, o.pose.position, o.position_sigma or 0.0
    return None


def differences(action: Perceive, obs: Observation) -> str:
    """The expected positions (and upright stances) the observation contradicts, in words
    ("" when none)."""
    seen = {o.name: o.pose for o in obs.objects}
    out = []
    for e in action.expect:
        pose = seen.get(e.object)
        if pose is None:
            out.append(f"the {e.object} was not seen")
            continue
        d = math.dist(pose.position, e.position)
        if d > e.tolerance:
            out.append(f"the {e.object} is {100 * d:.0f} cm from where the plan expects it")
        if e.max_tilt is not None and (tilt := pose.tilt()) > e.max_tilt:
            out.append(f"the {e.object} is not upright: it leans {math.degrees(tilt):.0f}°")
    return "; ".join(out)


def content_counts(action: CheckContent, obs: Observation) -> tuple[int, int]:
    """(spheres estimated, of them inferred and not seen) in the checked container: its
    ``particles_inside`` and ``particles_inferred`` ((0, 0) when it was not seen; no split
    known: none inferred)."""
    for o in obs.objects:
        if o.name == action.container:
            inside = o.particles_inside or 0
            return inside, min(inside, o.particles_inferred or 0)
    return 0, 0


def content_share(action: CheckContent, obs: Observation) -> float:
    """The share (0..1) of the content (``total_particles``) ``obs`` estimated in the checked
    container, the spheres seen and those inferred (0 when it was not seen)."""
    return content_counts(action, obs)[0] / max(1, obs.total_particles)


def seen_share(action: CheckContent, obs: Observation) -> float:
    """The share (0..1) of the content (``total_particles``) ``obs`` saw in the checked
    container: the spheres inferred behind its wall left out (0 when it was not seen)."""
    inside, inferred = content_counts(action, obs)
    return (inside - inferred) / max(1, obs.total_particles)


def content_seen(action: CheckContent, obs: Observation, look: int) -> str:
    """What look ``look`` (1: the first, 2: the second) counted in the checked container, in
    words: "the bowl holds 18 of 18 spheres, 15 seen (83 %) and 3 inferred behind its wall, at
    the first look"; "the bowl was not seen at the first look")."""
    inside, inferred = content_counts(action, obs)
    seen = inside - inferred
    which = "the first look" if look == 1 else "the second look"
    if all(o.name != action.container for o in obs.objects):
        return f"the {action.container} was not seen at {which}"
    share = f"{100 * seen / max(1, obs.total_particles):.0f} %"
    split = (
        f"{seen} seen ({share}) and {inferred} inferred behind its wall"
        if inferred
        else f"all seen ({share})"
    )
    return f"the {action.container} holds {inside} of {obs.total_particles} spheres, {split}, at {which}"


def content_shortfall(action: CheckContent, obs: Observation) -> str:
    """Why the container holds too little of the content, the spheres seen and inferred
    together, in words ("" when it holds at least ``min_fraction``); names the content ag_ex
    saw outside every container (spilled in view), if any."""
    share = content_share(action, obs)
    if share >= action.min_fraction:
        return ""
    spilled = obs.particles_outside
    seen_outside = f"; {spilled} of {obs.total_particles} seen outside it" if spilled else ""
    return (
        f"{action.container} holds only {100 * share:.0f} % of the content "
        f"(needs {100 * action.min_fraction:.0f} %){seen_outside}"
    )
