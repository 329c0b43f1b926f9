"""The plan's robot-side safety checks: a set-down lowers the held object with a contact guard
(L_EX ``MoveTool.guard``: the lower ends where the surface bears the object, even when the
hand holds it lower than planned), no other move has one (the pour's lower ends in the air
beside the bowl), and every grasp says where the hand must be (``Grasp.at``: the target of
the reach before it), so that ag_ex does not close a hand that is elsewhere."""

from __future__ import annotations

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.domain import SET_DOWN_GUARD_N, plan_task
from services.agents.planner.hfsm import to_hfsm
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Grasp, MoveTool
from shared.fipa_codec.languages.l_hfsm import Execute, PlanNode
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
from tests.agents.planner.kitchen import after_first_plan, knowledge

JAR = (0.80, 0.22, 0.90)
BOWL = (0.80, -0.20, 0.90)
TORSO_PLACE = -0.95  # velma/scenario.py: where plan #1 leaves the torso


def _commands(root: PlanNode) -> list[tuple[str, object]]:
    """Each executed leaf's path and L_EX command, in order."""
    return [(path, n.action.command) for path, n in root.leaves() if isinstance(n.action, Execute)]


def _pour_plans() -> tuple[list[tuple[str, object]], list[tuple[str, object]], list[PlanNode]]:
    """The pour's two plans (plan #1: take both out, put the bowl on the table; plan #2: pour)
    as (path, command) lists, and the HFSMs of plan #1's safe stops."""
    world = WorldModel()
    world.apply(
        WorldUpdate(
            stamp=0.0,
            objects=(ObjectUpdate(name="jar", pose=Pose(JAR)), ObjectUpdate(name="bowl", pose=Pose(BOWL))),
        )
    )
    first = plan_task(knowledge(world), ("pour", "jar", "bowl"), "pour(jar,bowl)")
    stops = [to_hfsm(actions)[0] for actions in first.safe_stops.values()]
    after_first_plan(world, TORSO_PLACE)
    second = plan_task(knowledge(world), ("pour", "jar", "bowl"), "pour(jar,bowl)", with_safe_stops=False)
    return _commands(to_hfsm(first.actions)[0]), _commands(to_hfsm(second.actions)[0]), stops


def test_only_set_downs_lower_with_a_guard_and_grasps_say_where_the_hand_is() -> None:
    plan1, plan2, stops = _pour_plans()
    moves = [(path, c) for path, c in plan1 + plan2 if isinstance(c, MoveTool)]
    guarded = {path: c.guard for path, c in moves if c.guard is not None}
    assert guarded == {"pour(jar,bowl)/place_bowl/set_down/lower": SET_DOWN_GUARD_N}
    (pour_lower,) = [c for path, c in moves if path.endswith("/pour_into_bowl/lower")]
    assert pour_lower.guard is None  # ends in the air beside the bowl: no contact to stop on
    # the safe stops put what the hands hold down with the same guarded lower
    assert stops
    for stop in stops:
        lowers = [c for path, c in _commands(stop) if path.endswith("/set_down/lower")]
        assert lowers and all(isinstance(c, MoveTool) and c.guard == SET_DOWN_GUARD_N for c in lowers)

    grasps = [(i, c) for i, (_, c) in enumerate(plan1) if isinstance(c, Grasp)]
    assert [c.arm.value for _, c in grasps] == ["left", "right"]  # the jar, then the bowl
    for i, grasp in grasps:
        reach_path, reach = plan1[i - 1]
        assert reach_path.endswith("/take/reach") and isinstance(reach, MoveTool)
        assert grasp.at == reach.target and grasp.arm == reach.arm
