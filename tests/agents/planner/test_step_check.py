"""a_km checks a generated plan step by step in the hypothetical state (paper §5.7;
services/agents/knowledge/plan_check.py): the real pour's plans pass every precondition; a
plan whose step cannot run — a target too small for the content, a grasp with a hand already
holding, a put-down where nothing fits — is refused with the step and the reason."""

from __future__ import annotations

from typing import Any

import pytest

from services.agents.knowledge.plan_check import StepRefused
from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.domain import find_plan
from services.agents.planner.goals import goal_query, steps
from services.agents.planner.hfsm import to_hfsm
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import (
    GraspStep,
    HypotheticalQuery,
    ObjectUpdate,
    SparqlQuery,
    WorldUpdate,
)
from tests.agents.planner.kitchen import after_first_plan, knowledge

scenario = pytest.importorskip("velma.scenario")

TASK = ("pour", "jar", "bowl")
JAR = (0.80, 0.22, 0.90)
BOWL = (0.80, -0.20, 0.90)
Action = tuple[Any, ...]


def seen_in_the_cabinet() -> WorldModel:
    """a_km before the pour's first plan: the jar and the bowl seen on the cabinet's shelf."""
    world = WorldModel()
    seen = (ObjectUpdate(name="jar", pose=Pose(JAR)), ObjectUpdate(name="bowl", pose=Pose(BOWL)))
    world.apply(WorldUpdate(stamp=0.0, objects=seen))
    return world


def ready_to_pour(jar_holds: int, bowl_holds: int) -> WorldModel:
    world = WorldModel()
    after_first_plan(world, scenario.TORSO_PLACE, jar_holds=jar_holds, bowl_holds=bowl_holds)
    return world


def plan(world: WorldModel) -> list[Action]:
    """The plan a_pl makes from what ``world`` knows now."""
    return find_plan(knowledge(world), TASK, "pour(jar,bowl)")


def check(world: WorldModel, actions: list[Action]) -> bool:
    """a_km's answer to a_pl's hypothetical query of ``actions`` (raises StepRefused)."""
    _, complete, _ = to_hfsm(actions)
    query = goal_query(TASK[0], list(TASK[1:]), actions, complete, knowledge(world))
    assert query is not None
    return world.answer(HypotheticalQuery(steps=steps(actions), query=query)).boolean is True


def see(world: WorldModel, *objects: ObjectUpdate) -> None:
    world.apply(WorldUpdate(stamp=10.0, objects=objects))


@pytest.mark.requirement("R2.2", "R2.3")
def test_the_real_pours_plans_pass_every_step() -> None:
    world = seen_in_the_cabinet()
    first = plan(world)
    operators = [s.operator for s in steps(first)]
    assert operators == ["grasp(jar, left)", "grasp(bowl, right)", "put(bowl, table)"]
    assert check(world, first)
    world = ready_to_pour(18, 0)
    second = plan(world)
    assert [s.operator for s in steps(second)] == ["pour(jar, bowl)"]
    assert check(world, second)
    assert world.object_info("bowl").particles == 0  # the real state is untouched


def test_a_steps_index_is_its_leaf_in_the_plan() -> None:
    world = seen_in_the_cabinet()
    actions = plan(world)
    root, _, _ = to_hfsm(actions)
    leaves = [path for path, _ in root.leaves()]
    assert [leaves[s.index - 1].rsplit("/", 2)[-2:] for s in steps(actions)] == [
        ["take", "grasp"],
        ["take", "grasp"],
        ["set_down", "put"],
    ]


@pytest.mark.requirement("R2.2", "R2.3")
def test_a_target_too_small_for_the_content_is_refused_at_the_pour() -> None:
    # the bowl already holds 70 (a_km's count); with the jar's 18 it would hold 88 of 84
    world = ready_to_pour(18, 70)
    with pytest.raises(StepRefused) as refused:
        check(world, plan(world))
    assert str(refused.value) == (
        "step 4 pour(jar, bowl): the bowl cannot take what the jar holds: 18 particles into 70, capacity 84"
    )
    world = ready_to_pour(18, 66)  # 84 of 84: it fits
    assert check(world, plan(world))


@pytest.mark.requirement("R2.2", "R2.3")
def test_a_grasp_with_a_hand_already_holding_is_refused() -> None:
    world = seen_in_the_cabinet()
    actions = plan(world)  # made while both hands were free
    assert check(world, actions)
    see(world, ObjectUpdate(name="cup", held_by="left_gripper"))  # a_km learns it after
    refused = r"^step 9 grasp\(jar, left\): the left hand already holds the cup$"
    with pytest.raises(StepRefused, match=refused):
        check(world, actions)


@pytest.mark.requirement("R2.2", "R2.3")
def test_a_put_down_where_nothing_fits_is_refused() -> None:
    world = seen_in_the_cabinet()
    actions = plan(world)
    place = world.placement("bowl", "table").positions[0]
    # the cup is seen on the table, 5 cm from the bowl's place: the two need 0.11 m
    cup = (place[0] + 0.05, place[1], place[2])
    see(world, ObjectUpdate(name="cup", location="table", relation="on", held_by=""))
    see(world, ObjectUpdate(name="cup", pose=Pose(cup)))
    with pytest.raises(StepRefused) as refused:
        check(world, actions)
    assert str(refused.value) == (
        f"step 30 put(bowl, table): nothing fits on the table at ({place[0]:.2f}, {place[1]:.2f}): "
        "the cup stands there (0.050 m away, the two need 0.110 m)"
    )
    see(world, ObjectUpdate(name="cup", pose=Pose((place[0] + 0.12, place[1], place[2]))))
    assert check(world, actions)  # 0.12 m away: both fit


def test_a_put_down_off_the_furniture_is_refused() -> None:
    world = seen_in_the_cabinet()
    actions = plan(world)
    (i,) = [n for n, a in enumerate(actions) if a[0] == "a_put"]
    name, path, obj, furniture, relation, (x, _y, z) = actions[i]
    off = [*actions[:i], (name, path, obj, furniture, relation, (x, -0.33, z)), *actions[i + 1 :]]
    with pytest.raises(StepRefused, match=r"step 30 put\(bowl, table\): the bowl does not fit on the table"):
        check(world, off)


@pytest.mark.parametrize(
    ("jar", "reason"),
    [
        (ObjectUpdate(name="jar", particles=0), "the jar is empty"),
        (ObjectUpdate(name="jar", held_by=""), "the jar is not in a hand"),
    ],
)
def test_a_pour_needs_the_source_in_a_hand_and_holding_content(jar: ObjectUpdate, reason: str) -> None:
    world = ready_to_pour(18, 0)
    actions = plan(world)
    see(world, jar)
    with pytest.raises(StepRefused, match=rf"^step 4 pour\(jar, bowl\): {reason}$"):
        check(world, actions)


def test_a_step_about_something_a_km_does_not_know_is_refused_with_the_step() -> None:
    world = seen_in_the_cabinet()
    teapot = GraspStep(index=3, object="teapot", arm="left")
    with pytest.raises(StepRefused, match=r"^step 3 grasp\(teapot, left\): nothing is known about 'teapot'$"):
        world.answer(HypotheticalQuery(steps=(teapot,), query=SparqlQuery("ASK { }")))


def test_a_pour_whose_jar_ran_out_is_finished_without_pouring_again() -> None:
    # a_ta restarted mid-tilt after the content ran out: the replan must not pour an empty jar
    # (a_km would refuse it) but bring the jar upright and check the bowl
    world = ready_to_pour(0, 18)
    actions = plan(world)
    assert [s.operator for s in steps(actions)] == []
    names = [a[0] for a in actions]
    assert "a_tilt" not in names and names[-1] == "a_check"
    assert any(a[0] == "a_move" and a[1].endswith("/clear_view") for a in actions)
    assert check(world, actions)


def test_a_malformed_capacity_refuses_the_pour_naming_it() -> None:
    from rdflib import Literal

    from services.agents.knowledge.world_model import ROCO

    world = ready_to_pour(18, 0)
    actions = plan(world)
    world.graph.set((ROCO.bowl, ROCO.capacity, Literal("a lot")))
    with pytest.raises(StepRefused, match=r"^step 4 pour\(jar, bowl\): bowl: capacity is not a whole number"):
        check(world, actions)
