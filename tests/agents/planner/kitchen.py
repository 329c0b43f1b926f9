"""What a_pl would know after its initialize behaviour, taken straight from a_km's world model:
the planner tests' shared set-up."""

from __future__ import annotations

import math

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.knowledge import ARMS, Knowledge
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate


def knowledge(world: WorldModel, furniture: tuple[str, ...] = ("table",)) -> Knowledge:
    """Every physical object and both grippers, the jar's and the bowl's grasps, their places
    on ``furniture`` (those a_km knows), and the jar-into-bowl pour."""
    k = Knowledge()
    for name in [*world.physical_objects(), "left_gripper", "right_gripper"]:
        k.objects[name] = world.object_info(name)
    for obj in ("jar", "bowl"):
        for arm in ARMS:
            k.grasps[(obj, arm)] = world.grasps(obj, arm)
        for where in furniture:
            placement = world.placement(obj, where)
            if placement is not None:
                k.placements[(obj, where)] = placement
    k.pours[("jar", "bowl")] = world.pour("jar", "bowl")
    return k


def after_first_plan(
    world: WorldModel, torso_yaw: float, jar_holds: int | None = None, bowl_holds: int | None = None
) -> None:
    """Apply to ``world`` what the pour's first plan leaves behind: the bowl put on the table and
    seen at its place, the jar held in the left hand and seen turned with the torso to
    ``torso_yaw`` (rad); the containers' counts when given (None: not observed)."""
    place = world.placement("bowl", "table").positions[0]
    jar = Pose((0.5, -0.1, 1.0), (math.cos(torso_yaw / 2), 0.0, 0.0, math.sin(torso_yaw / 2)))
    world.apply(WorldUpdate(stamp=1.0, objects=(ObjectUpdate(name="jar", held_by="left_gripper"),)))
    put = ObjectUpdate(name="bowl", location="table", relation="on", held_by="")
    world.apply(WorldUpdate(stamp=2.0, objects=(put,)))
    seen = (
        ObjectUpdate(name="bowl", pose=Pose(place), particles=bowl_holds),
        ObjectUpdate(name="jar", pose=jar, particles=jar_holds),
    )
    world.apply(WorldUpdate(stamp=3.0, objects=seen))
