"""a_pl's goal check (services/agents/planner/goals.py): the goal is evaluated by a_km in the
hypothetical state the plan's operators produce (paper §5.7), and a plan that does not reach
the goal is rejected; the plan's own check step is not taken as its effect."""

from __future__ import annotations

import pytest

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.domain import find_plan
from services.agents.planner.goals import effects, goal_query
from services.agents.planner.hfsm import to_hfsm
from shared.fipa_codec.languages.l_hfsm import CheckContent
from shared.fipa_codec.languages.l_wm import HypotheticalQuery
from tests.agents.planner.kitchen import after_first_plan, knowledge

scenario = pytest.importorskip("velma.scenario")

TASK = ("pour", "jar", "bowl")


def ready_to_pour(jar_holds: int | None) -> WorldModel:
    """a_km after the first plan: the bowl on the table (seen there, empty), the jar held
    (seen, holding ``jar_holds`` particles; None: never counted)."""
    world = WorldModel()
    after_first_plan(world, scenario.TORSO_PLACE, jar_holds=jar_holds, bowl_holds=0)
    return world


def holds(world: WorldModel, actions: list[tuple[object, ...]], complete: bool = True) -> bool:
    query = goal_query(TASK[0], list(TASK[1:]), actions, complete, knowledge(world))
    assert query is not None
    answer = world.answer(HypotheticalQuery(changes=effects(actions), query=query))
    return answer.boolean is True


@pytest.mark.requirement("R2.2", "R2.3")
def test_the_complete_pour_plan_reaches_its_goal_in_the_hypothetical_state() -> None:
    world = ready_to_pour(18)
    actions = find_plan(knowledge(world), TASK, "pour(jar,bowl)")
    _, complete, _ = to_hfsm(actions)
    assert complete
    assert holds(world, actions)
    # the real state is untouched: the bowl is still empty in a_km
    assert world.object_info("bowl").particles == 0 and world.object_info("jar").particles == 18


def test_a_plan_that_does_not_pour_is_rejected_though_it_ends_with_the_check() -> None:
    world = ready_to_pour(18)
    actions = find_plan(knowledge(world), TASK, "pour(jar,bowl)")
    no_pour = [a for a in actions if a[0] != "a_poured"]
    assert no_pour[-1][0] == "a_check"  # the plan still checks the bowl, as a complete plan does
    assert not holds(world, no_pour)


def test_a_pour_of_less_than_the_required_share_is_rejected() -> None:
    world = ready_to_pour(18)
    actions = find_plan(knowledge(world), TASK, "pour(jar,bowl)")
    (i,) = [n for n, a in enumerate(actions) if a[0] == "a_poured"]
    name, path, src, dst, _amount, into = actions[i]
    short = [*actions[:i], (name, path, src, dst, 16, into), *actions[i + 1 :]]  # 16 < 0.9 × 18
    assert not holds(world, short)
    enough = [*actions[:i], (name, path, src, dst, 17, into), *actions[i + 1 :]]
    assert holds(world, enough)


def test_a_pour_whose_source_content_a_km_does_not_know_cannot_be_shown_to_reach_the_goal() -> None:
    world = ready_to_pour(None)
    actions = find_plan(knowledge(world), TASK, "pour(jar,bowl)")
    assert not holds(world, actions)


def test_the_pour_effect_is_knowledge_only_and_the_check_stays_a_test_of_the_world() -> None:
    world = ready_to_pour(18)
    actions = find_plan(knowledge(world), TASK, "pour(jar,bowl)")
    root, _, _ = to_hfsm(actions)
    names = [path.rsplit("/", 1)[-1] for path, _ in root.leaves()]
    assert "poured" not in names
    checks = [n.action for _, n in root.leaves() if isinstance(n.action, CheckContent)]
    assert [(c.container, c.min_fraction) for c in checks] == [("bowl", 0.9)]
    assert all(u.particles != 1 for u in effects(actions) if u.name == "bowl")
