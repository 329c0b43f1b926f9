"""Every refusal of a_km's plan check (services/agents/knowledge/plan_check.py) and of the goal
check built on it (``WorldModel.hypothetical``, paper §5.7), one test each: the test plants the
fault that must make it fire (in the world a_km knows, or in the step a_pl proposes) and asserts
the reason in words; where it helps, the same step without the fault passes, so that it is the
fault that is refused. scripts/mutate_checks.py deletes each refusal in turn and runs this file:
exactly the refusal's test fails.

The kitchen is a_km's own (o_roco.ttl, kitchen.ttl): the jar, the bowl and the cup in the
cabinet, both hands free; the jar has left-hand grasps valid in the cabinet and on the table,
the bowl and the cup right-hand grasps valid anywhere; the bowl takes 84 particles."""

from __future__ import annotations

import msgspec
import pytest
from rdflib import Literal

from services.agents.knowledge.plan_check import StepRefused, capacity, place_area, refusal
from services.agents.knowledge.world_model import ROCO, KnowledgeError, UnsupportedQuery, WorldModel
from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_wm import (
    GraspStep,
    HypotheticalQuery,
    ObjectQuery,
    ObjectUpdate,
    PlanStep,
    PourStep,
    PutStep,
    SparqlQuery,
    WorldUpdate,
)

BOWL_PLACE: Vec3 = (0.31, -0.42, 0.75)
"""The bowl's place on the table (kitchen.ttl ``roco:table_bowl_place``)."""

GRASP_JAR = GraspStep(index=1, object="jar", arm="left")
PUT_BOWL = PutStep(index=2, object="bowl", furniture="table", relation="on", position=BOWL_PLACE)
POUR = PourStep(index=3, source="jar", target="bowl")
GRASP_BOWL = GraspStep(
    index=1, object="bowl", arm="right", changes=(ObjectUpdate(name="bowl", held_by="right_gripper"),)
)
"""The bowl's grasp with the effect a_pl declares for it (services/agents/planner/goals.py)."""
PUT_BOWL_DOWN = msgspec.structs.replace(
    PUT_BOWL,
    changes=(ObjectUpdate(name="bowl", location="table", relation="on", held_by="", pose=Pose(BOWL_PLACE)),),
)
"""The bowl's put-down on the table with the effect a_pl declares for it."""


def kitchen(*changes: ObjectUpdate) -> WorldModel:
    """a_km's kitchen as it starts, then ``changes`` observed (at t = 1 s)."""
    world = WorldModel()
    if changes:
        world.apply(WorldUpdate(stamp=1.0, objects=changes))
    return world


def bowl_in_hand(*changes: ObjectUpdate) -> WorldModel:
    """The kitchen with the bowl in the right hand, then ``changes``."""
    return kitchen(ObjectUpdate(name="bowl", held_by="right_gripper"), *changes)


def ready_to_pour(jar: int | None, bowl: int = 0) -> WorldModel:
    """The jar in the left hand holding ``jar`` particles (None: never counted), the bowl on the
    table at its place holding ``bowl`` (a_km's counts)."""
    held = ObjectUpdate(name="jar", held_by="left_gripper", particles=jar)
    put = ObjectUpdate(name="bowl", location="table", relation="on", pose=Pose(BOWL_PLACE), particles=bowl)
    return kitchen(held, put)


def cup_on_the_table(dx: float) -> ObjectUpdate:
    """The cup seen on the table ``dx`` m along x from the bowl's place."""
    at = (BOWL_PLACE[0] + dx, BOWL_PLACE[1], BOWL_PLACE[2])
    return ObjectUpdate(name="cup", location="table", relation="on", pose=Pose(at))


def plan_check(world: WorldModel, steps: tuple[PlanStep, ...], goal: str) -> bool | None:
    """a_km's answer to a_pl's hypothetical query: ``steps``, then the ASK ``goal``."""
    return world.answer(HypotheticalQuery(steps=steps, query=SparqlQuery(goal))).boolean


# ---- grasp(object, arm) ------------------------------------------------------------------------


def test_a_grasp_with_a_hand_that_already_holds_something_is_refused() -> None:
    """Fault: the cup is in the left hand when the plan has that hand grasp the jar."""
    assert refusal(kitchen(), GRASP_JAR) is None
    world = kitchen(ObjectUpdate(name="cup", held_by="left_gripper"))
    assert refusal(world, GRASP_JAR) == "the left hand already holds the cup"


def test_a_grasp_of_an_object_the_other_hand_holds_is_refused() -> None:
    """Fault: the jar is in the right hand when the plan has the left hand grasp it."""
    world = kitchen(ObjectUpdate(name="jar", held_by="right_gripper"))
    assert refusal(world, GRASP_JAR) == "the jar is already held by the right hand"


def test_a_grasp_with_a_hand_the_object_has_no_grasp_for_is_refused() -> None:
    """Fault: the plan has the left hand grasp the bowl; the kitchen knows only right-hand
    grasps of the bowl."""
    world = kitchen()
    assert refusal(world, GraspStep(index=1, object="bowl", arm="right")) is None
    left = GraspStep(index=1, object="bowl", arm="left")
    assert refusal(world, left) == "the bowl has no grasp for the left hand"


def test_a_grasp_with_no_grasp_valid_where_the_object_stands_is_refused() -> None:
    """Fault: the jar stands on the floor; its left-hand grasps are valid only in the cabinet
    and on the table (``roco:graspOn``)."""
    assert refusal(kitchen(ObjectUpdate(name="jar", location="table", relation="on")), GRASP_JAR) is None
    world = kitchen(ObjectUpdate(name="jar", location="floor", relation="on"))
    assert refusal(world, GRASP_JAR) == "the left hand has no grasp of the jar on the floor"


def test_a_step_about_an_object_a_km_does_not_know_is_refused() -> None:
    """Fault: the plan grasps a teapot; a_km knows nothing about a teapot (a KnowledgeError
    becomes the reason instead of escaping the check)."""
    teapot = GraspStep(index=1, object="teapot", arm="left")
    assert refusal(kitchen(), teapot) == "nothing is known about 'teapot'"


# ---- put(object, furniture) --------------------------------------------------------------------


def test_a_put_down_of_an_object_no_hand_holds_is_refused() -> None:
    """Fault: the bowl is still in the cabinet (nothing grasped it) when the plan puts it on the
    table."""
    assert refusal(bowl_in_hand(), PUT_BOWL) is None
    assert refusal(kitchen(), PUT_BOWL) == "the bowl is not in a hand"


def test_a_put_down_whose_footprint_leaves_the_furniture_is_refused() -> None:
    """Fault: the bowl (ø 0.14 m) put down at y = -0.33: it reaches past the table's edge at
    y = -0.35 (``roco:placeArea``)."""
    off = msgspec.structs.replace(PUT_BOWL, position=(0.31, -0.33, 0.75))
    assert refusal(bowl_in_hand(), off) == "the bowl does not fit on the table at (0.31, -0.33)"


def test_a_put_down_where_another_object_stands_is_refused() -> None:
    """Fault: the cup (ø 0.08 m) stands on the table 5 cm from the bowl's place; the two
    footprints need 0.11 m."""
    assert refusal(bowl_in_hand(cup_on_the_table(0.12)), PUT_BOWL) is None
    assert refusal(bowl_in_hand(cup_on_the_table(0.05)), PUT_BOWL) == (
        "nothing fits on the table at (0.31, -0.42): "
        "the cup stands there (0.050 m away, the two need 0.110 m)"
    )


@pytest.mark.parametrize("area", ["0.0 -0.95 0.6", "0.0 -0.95 0.6 far"])
def test_a_place_area_that_is_not_four_numbers_is_refused_naming_the_furniture(area: str) -> None:
    """Fault: the table's ``roco:placeArea`` is three numbers, or not numbers. (The step check
    turns the KnowledgeError into the put's reason, as for an unknown object.)"""
    world = bowl_in_hand()
    world.graph.set((ROCO.table, ROCO.placeArea, Literal(area)))
    with pytest.raises(
        KnowledgeError, match=r"^table: placeArea is not four numbers \(x0 y0 x1 y1\): "
    ) as bad:
        place_area(world, "table")
    assert area in str(bad.value)


# ---- pour(source, target) ----------------------------------------------------------------------


def test_a_pour_from_a_source_no_hand_holds_is_refused() -> None:
    """Fault: the jar (18 particles) is still in the cabinet when the plan pours from it."""
    world = kitchen(ObjectUpdate(name="jar", particles=18))
    assert refusal(world, POUR) == "the jar is not in a hand"


def test_a_pour_whose_source_content_is_unknown_is_refused() -> None:
    """Fault: a_km never counted what the jar in the hand holds."""
    assert refusal(ready_to_pour(18), POUR) is None
    assert refusal(ready_to_pour(None), POUR) == "how much the jar holds is not known"


def test_a_pour_from_an_empty_source_is_refused() -> None:
    """Fault: the jar in the hand holds nothing (a_km's count: 0)."""
    assert refusal(ready_to_pour(0), POUR) == "the jar is empty"


def test_a_pour_into_a_target_whose_capacity_is_unknown_is_refused() -> None:
    """Fault: the kitchen does not state what the bowl takes (its ``roco:capacity`` is gone)."""
    world = ready_to_pour(18)
    world.graph.remove((ROCO.bowl, ROCO.capacity, None))
    assert refusal(world, POUR) == "how much the bowl takes is not known"


def test_a_pour_into_a_target_too_small_for_the_content_is_refused() -> None:
    """Fault: the bowl (capacity 84) cannot take the jar's particles: 70 + 18, or 90 into it
    empty; 66 + 18 = 84 fills it exactly and passes."""
    assert refusal(ready_to_pour(18, bowl=66), POUR) is None
    assert refusal(ready_to_pour(18, bowl=70), POUR) == (
        "the bowl cannot take what the jar holds: 18 particles into 70, capacity 84"
    )
    assert (
        refusal(ready_to_pour(90), POUR)
        == "the bowl cannot take what the jar holds: 90 particles, capacity 84"
    )


def test_a_capacity_that_is_not_a_whole_number_is_refused_naming_the_container() -> None:
    """Fault: the bowl's ``roco:capacity`` is not a whole number. (The step check turns the
    KnowledgeError into the pour's reason, as for an unknown object.)"""
    world = ready_to_pour(18)
    world.graph.set((ROCO.bowl, ROCO.capacity, Literal("a lot")))
    with pytest.raises(KnowledgeError, match=r"^bowl: capacity is not a whole number: ") as bad:
        capacity(world, "bowl")
    assert "a lot" in str(bad.value)


# ---- the goal check: a_pl's HypotheticalQuery (WorldModel.hypothetical) ------------------------


@pytest.mark.requirement("R2.3")
def test_the_goal_check_refuses_the_first_step_that_cannot_run_in_the_state_before_it() -> None:
    """Fault: the plan has the right hand grasp the bowl again in step 2, after step 1 grasped it;
    the step is refused from step 1's effect (in the real state it can run), named with its
    reason, and the steps after it are not checked."""
    world = kitchen()
    assert refusal(world, GRASP_BOWL) is None
    again = msgspec.structs.replace(GRASP_BOWL, index=2)
    goal = "ASK { roco:bowl roco:on roco:table }"
    assert plan_check(world, (GRASP_BOWL, PUT_BOWL_DOWN), goal) is True
    with pytest.raises(StepRefused) as refused:
        plan_check(
            world, (GRASP_BOWL, again, PUT_BOWL_DOWN, GraspStep(index=4, object="teapot", arm="left")), goal
        )
    why = refusal(bowl_in_hand(), again)  # what step 2 meets: the bowl in the right hand
    assert why is not None and str(refused.value) == f"step 2 grasp(bowl, right): {why}"
    assert world.object_info("bowl").location == "cabinet"  # the real state is untouched


def test_the_goal_check_answers_false_for_steps_that_run_but_miss_the_goal() -> None:
    """Fault: the plan grasps the bowl but never puts it down; the goal is the bowl on the table."""
    assert plan_check(kitchen(), (GRASP_BOWL,), "ASK { roco:bowl roco:on roco:table }") is False


def test_a_hypothetical_query_inside_a_hypothetical_query_is_refused() -> None:
    """Fault: the query to answer after the steps is itself a hypothetical query."""
    inner = HypotheticalQuery(query=ObjectQuery("jar"))
    outer = HypotheticalQuery(steps=(GRASP_JAR,), query=inner)  # type: ignore[arg-type]
    with pytest.raises(UnsupportedQuery, match=r"^a hypothetical query inside a hypothetical query$"):
        kitchen().answer(outer)


# ---- the goal check takes each step's effects from a_km's reading, not from what a_pl declares -----


def test_a_pour_whose_declared_effect_overstates_the_content_does_not_reach_the_goal() -> None:
    """Fault: a_pl declares that the pour leaves 90 particles in the bowl; by a_km's counts the
    jar's 20 join the bowl's 64: 84 (a full bowl). The goal, 90 in the bowl, must not hold."""
    world = ready_to_pour(20, bowl=64)
    pour = msgspec.structs.replace(
        POUR, changes=(ObjectUpdate(name="jar", particles=0), ObjectUpdate(name="bowl", particles=90))
    )
    assert refusal(world, pour) is None  # the pour can run: 20 + 64 fits the bowl's 84
    assert plan_check(world, (pour,), "ASK { roco:bowl roco:particles ?n . FILTER(?n >= 90) }") is False


def test_a_grasp_whose_declared_effect_puts_something_elsewhere_does_not_reach_the_goal() -> None:
    """Fault: a_pl declares that grasping the jar puts the bowl on the table; no step puts the
    bowl anywhere, so the goal, the bowl on the table, must not hold."""
    grasp = msgspec.structs.replace(
        GRASP_JAR, changes=(ObjectUpdate(name="bowl", location="table", relation="on"),)
    )
    assert plan_check(kitchen(), (grasp,), "ASK { roco:bowl roco:on roco:table }") is False
