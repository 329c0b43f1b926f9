"""A fetch looks at the object and checks it is where a_km says before the hand comes near it
(with the head camera a hand over the object, or a head still turned to the cabinet,
would hide it)."""

from __future__ import annotations

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.domain import plan_task
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
from tests.agents.planner.kitchen import knowledge as kitchen_knowledge
from velma.scenario import BOWL_PLACE_POSITION

BOWL_ON_TABLE = BOWL_PLACE_POSITION


def test_the_bowl_on_the_table_is_looked_at_and_seen_before_the_hand_moves() -> None:
    world = WorldModel()
    world.apply(
        WorldUpdate(
            stamp=0.0,
            objects=(
                ObjectUpdate(name="jar", pose=Pose((0.70, 0.20, 0.85))),
                ObjectUpdate(name="bowl", pose=Pose(BOWL_ON_TABLE), location="table", relation="on"),
            ),
        )
    )
    result = plan_task(kitchen_knowledge(world, ("table", "cabinet")), ("return", "bowl"), "return(bowl)")
    steps = [a[1].rsplit("/", 2)[-1] for a in result.actions if "/fetch_bowl/" in a[1]]
    look = steps.index("look_at_bowl")
    assert steps[look + 1] == "see_bowl"
    assert look < steps.index("open_hand") < steps.index("pregrasp")
    (looked,) = [a for a in result.actions if a[1].endswith("/look_at_bowl")]
    assert tuple(looked[2]) == BOWL_ON_TABLE  # the head turns to where a_km has the bowl
