"""The preconditions of a plan's steps, checked by a_km in the hypothetical state of its
knowledge base (paper §5.7: "the plan is checked in the hypothetical state of the knowledge
base"), in its own terms: O_RoCo (o_roco.ttl) and the kitchen's facts (kitchen.ttl).

- grasp(object, arm): the hand of ``arm`` holds nothing, nobody else holds the object, and
  the object has a grasp affordance for that hand valid where it stands (``roco:graspOn``).
- put(object, furniture): the object is held; its footprint (the larger horizontal extent of
  its ``roco:size``, taken as a disc) lies inside the furniture's ``roco:placeArea``, and no
  other object in or on that furniture whose position a_km knows stands within the two
  footprints' radii (centres compared horizontally). Objects whose position a_km does not
  know are not counted; an object whose size it does not know counts as a point.
- pour(source, target): the source is held and holds particles (a_km's count); the target's
  ``roco:capacity`` takes what it holds plus what the source holds.

:func:`refusal` returns the reason in words, or None when every precondition holds;
:func:`effects` what a step that can run changes, by a_km's own reading of the operator. The
hypothetical state takes these, not the ``changes`` a_pl declares in the step: a plan reaches
its goal by what its steps do, not by what its author says they do.
"""

from __future__ import annotations

import math

from services.agents.knowledge.world_model import ROCO, KnowledgeError, WorldModel
from shared.fipa_codec.languages.common import Vec3
from shared.fipa_codec.languages.l_wm import GraspStep, ObjectInfo, ObjectUpdate, PlanStep, PourStep, PutStep


class StepRefused(KnowledgeError):
    """A plan's step whose precondition does not hold in the hypothetical state; the message
    names the step ("step 7 pour(jar, cup)") and the reason. a_km answers it with ``failure``."""


def refusal(world: WorldModel, step: PlanStep) -> str | None:
    """Why ``step`` cannot run in the state ``world`` holds (words), or None when it can. A
    step about an individual nothing is known about, or whose facts are malformed, cannot run:
    the reason is the KnowledgeError's."""
    try:
        if isinstance(step, GraspStep):
            return _grasp(world, step)
        if isinstance(step, PutStep):
            return _put(world, step)
        return _pour(world, step)
    except KnowledgeError as exc:
        return str(exc)


def effects(world: WorldModel, step: PlanStep) -> tuple[ObjectUpdate, ...]:
    """What ``step``, which can run in the state ``world`` holds (:func:`refusal` gave None),
    changes in it: a grasp puts the object in the hand of its arm; a put takes it out of the
    hand and stands it ``relation`` the furniture at the step's position (world, m); a pour
    empties the source into the target (a_km's counts of particles)."""
    if isinstance(step, GraspStep | PutStep):
        return step.effects()  # the operator's meaning in L_WM, not the step's declared changes
    poured = world.object_info(step.source).particles or 0
    there = world.object_info(step.target).particles or 0
    return (
        ObjectUpdate(name=step.source, particles=0),
        ObjectUpdate(name=step.target, particles=there + poured),
    )


def _hand(gripper: str) -> str:
    return gripper.removesuffix("_gripper") + " hand"


def _held_by(world: WorldModel, gripper: str) -> list[str]:
    node = world.graph.subjects(ROCO.heldBy, ROCO[gripper])
    return sorted(str(n).removeprefix(str(ROCO)) for n in node)


def _grasp(world: WorldModel, step: GraspStep) -> str | None:
    gripper = f"{step.arm}_gripper"
    holding = _held_by(world, gripper)
    if holding:
        return f"the {_hand(gripper)} already holds the {holding[0]}"
    info = world.object_info(step.object)
    if info.held_by:
        return f"the {step.object} is already held by the {_hand(info.held_by)}"
    grasps = world.grasps(step.object, step.arm)
    if not grasps:
        return f"the {step.object} has no grasp for the {step.arm} hand"
    where = info.location or ""
    if where and not any(not g.on or where in g.on for g in grasps):
        return f"the {step.arm} hand has no grasp of the {step.object} {info.relation or 'at'} the {where}"
    return None


def footprint(info: ObjectInfo) -> float:
    """The diameter (m) of the disc an object stands on: the larger of its horizontal extents
    (``roco:size``); 0 when its size is not known."""
    return max(info.size[0], info.size[1]) if info.size is not None else 0.0


def _put(world: WorldModel, step: PutStep) -> str | None:
    info = world.object_info(step.object)
    if not info.held_by:
        return f"the {step.object} is not in a hand"
    radius = footprint(info) / 2
    x, y = step.position[0], step.position[1]
    area = place_area(world, step.furniture)
    if area is not None and not (
        area[0] + radius <= x <= area[2] - radius and area[1] + radius <= y <= area[3] - radius
    ):
        return f"the {step.object} does not fit {step.relation} the {step.furniture} at {_xy(step.position)}"
    for other in _standing(world, step.furniture):
        if other.name == step.object or other.pose is None:
            continue
        apart = math.dist((x, y), other.pose.position[:2])
        need = radius + footprint(other) / 2
        if apart < need:
            return (
                f"nothing fits {step.relation} the {step.furniture} at {_xy(step.position)}: the "
                f"{other.name} stands there ({apart:.3f} m away, the two need {need:.3f} m)"
            )
    return None


def _xy(p: Vec3) -> str:
    return f"({p[0]:.2f}, {p[1]:.2f})"


def _standing(world: WorldModel, furniture: str) -> list[ObjectInfo]:
    node = ROCO[furniture]
    names = {*world.graph.subjects(ROCO.on, node), *world.graph.subjects(ROCO["in"], node)}
    return [world.object_info(str(n).removeprefix(str(ROCO))) for n in sorted(names, key=str)]


def place_area(world: WorldModel, furniture: str) -> tuple[float, float, float, float] | None:
    """The furniture's ``roco:placeArea`` (x0, y0, x1, y1: world, m), None when not stated.
    Raises KnowledgeError for a value that is not four numbers."""
    value = world.graph.value(ROCO[furniture], ROCO.placeArea)
    if value is None:
        return None
    try:
        v = [float(t) for t in str(value).split()]
    except ValueError:
        v = []
    if len(v) != 4:
        raise KnowledgeError(f"{furniture}: placeArea is not four numbers (x0 y0 x1 y1): {value!r}")
    return (v[0], v[1], v[2], v[3])


def capacity(world: WorldModel, container: str) -> int | None:
    """How many particles ``container`` takes (``roco:capacity``), None when not stated.
    Raises KnowledgeError for a value that is not a whole number."""
    value = world.graph.value(ROCO[container], ROCO.capacity)
    if value is None:
        return None
    try:
        return int(str(value))
    except ValueError:
        raise KnowledgeError(f"{container}: capacity is not a whole number: {value!r}") from None


def _pour(world: WorldModel, step: PourStep) -> str | None:
    src, dst = world.object_info(step.source), world.object_info(step.target)
    if not src.held_by:
        return f"the {step.source} is not in a hand"
    if src.particles is None:
        return f"how much the {step.source} holds is not known"
    if src.particles == 0:
        return f"the {step.source} is empty"
    room = capacity(world, step.target)
    if room is None:
        return f"how much the {step.target} takes is not known"
    there = dst.particles or 0
    if there + src.particles > room:
        held = f"{src.particles} particles" + (f" into {there}" if there else "")
        return f"the {step.target} cannot take what the {step.source} holds: {held}, capacity {room}"
    return None
