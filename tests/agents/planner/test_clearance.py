"""What a hand holds passes clear of what stands: a plan's torso turns and carries never sweep a
held object through a standing one (services/agents/planner/clearance.py). A stop while both
hands hold something puts them down in the order that keeps the second clear of the first
(the bowl first when it is carried to the table: put after the jar, the bowl was turned over
the jar and carried down through it, and the next pour found the jar knocked over); an object
put down but not seen since is looked for where it was put."""

from __future__ import annotations

from typing import Any

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner import domain
from services.agents.planner.clearance import ABOVE_M, Body, carry_meets, turn_meets
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
from tests.agents.planner.kitchen import knowledge

JAR = Body("jar", (0.11, -0.46, 0.75), 0.045, 0.12)  # standing at its table place (kitchen.ttl)
BOWL_SIZE = (0.14, 0.14, 0.06)


def test_a_turn_meets_what_stands_on_its_arc_unless_it_passes_high_enough_above() -> None:
    arc_start = (-0.168, -0.463)  # turned by +0.55 rad this ends beside the jar's place
    low = Body.of("bowl", (*arc_start, 0.87 + 0.025), BOWL_SIZE)  # 25 mm over the jar's top
    assert turn_meets(low, 0.55, [JAR]) == "jar"
    high = Body.of("bowl", (*arc_start, 0.87 + ABOVE_M + 0.001), BOWL_SIZE)
    assert turn_meets(high, 0.55, [JAR]) is None
    assert turn_meets(low, -0.55, [JAR]) is None  # the other way round the torso
    assert turn_meets(low, 0.2, [JAR]) is None  # stops before it


def test_a_carry_meets_what_stands_on_its_line() -> None:
    bowl = Body.of("bowl", (0.099, -0.482, 0.9), BOWL_SIZE)
    assert carry_meets(bowl, (0.34, -0.46, 0.835), [JAR]) == "jar"  # down through the jar's top
    assert carry_meets(bowl, (0.11, -0.30, 0.95), [JAR]) is None  # up and away
    far = Body.of("bowl", (0.60, -0.46, 0.80), BOWL_SIZE)
    assert carry_meets(far, (0.34, -0.46, 0.80), [JAR]) is None  # stops short of it


def _start_world() -> WorldModel:
    """a_km at the start: jar and bowl standing in the cabinet."""
    world = WorldModel()
    world.apply(
        WorldUpdate(
            stamp=0.0,
            objects=(
                ObjectUpdate(name="jar", pose=Pose((0.7, 0.2, 0.85))),
                ObjectUpdate(name="bowl", pose=Pose((0.7, -0.2, 0.85))),
            ),
        )
    )
    return world


def _start() -> Any:
    """a_km's answers at the start."""
    return knowledge(_start_world())


def _sweeps(s: Any, actions: list[tuple[Any, ...]]) -> list[str]:
    """Replay ``actions`` from ``s``; each turn or carry that sweeps a held object through a
    standing one, as "path: held → standing"."""
    met = []
    for name, path, *args in actions:
        standing = domain._standing(s)
        for held in (o for o in s.holding.values() if o is not None):
            size = s.k.objects[held].size
            body = Body.of(held, s.pose[held].position, size)
            if name == "a_face" and s.torso is not None:
                hit = turn_meets(body, args[0] - s.torso, standing)
            elif name == "a_move" and path.endswith("/carry") and held == s.holding[args[0]]:
                to = domain.geo.compose(args[1], domain.geo.inverse(s.grip[held])).position
                hit = carry_meets(body, to, standing)
            else:
                hit = None
            if hit is not None:
                met.append(f"{path}: {held} → {hit}")
        domain.ACTIONS[name](s, path, *args)
    return met


def test_no_safe_stop_of_the_pour_sweeps_a_held_object_through_a_standing_one() -> None:
    k = _start()
    plan = domain.plan_task(k, ("pour", "jar", "bowl"), "pour(jar,bowl)")
    assert len(plan.safe_stops) >= 4
    for key, stop in plan.safe_stops.items():
        s = domain.initial_state(k, {})  # replayed to the first action this safe stop is for
        for (name, path, *args), on_cancel in zip(plan.actions, plan.on_cancel, strict=True):
            if on_cancel == key:
                break
            domain.ACTIONS[name](s, path, *args)
        assert _sweeps(s, stop) == [], key
    # a stop while the bowl is carried to the table (the jar in the other hand): the bowl first
    carry = next(i for i, a in enumerate(plan.actions) if a[1] == "pour(jar,bowl)/place_bowl/carry")
    stop = plan.safe_stops[plan.on_cancel[carry] or ""]
    assert [a[2] for a in stop if a[0] == "a_put"] == ["bowl", "jar"]


def test_a_bowl_put_on_the_table_but_not_seen_since_is_looked_for_at_its_place() -> None:
    # a stop came during the bowl's set-down (atomic: it is finished) and the safe stop then put
    # the jar down: a_km knows the bowl is on the table, its last seen pose is in the cabinet
    world = _start_world()
    for update in (
        ObjectUpdate(name="jar", held_by="left_gripper"),
        ObjectUpdate(name="bowl", held_by="right_gripper"),
        ObjectUpdate(name="bowl", held_by="", location="table", relation="on"),
        ObjectUpdate(name="jar", held_by="", location="table", relation="on"),
    ):
        world.apply(WorldUpdate(stamp=-1.0, objects=(update,)))
    world.apply(WorldUpdate(stamp=5.0, objects=(ObjectUpdate(name="jar", pose=Pose(JAR.at)),)))
    k = knowledge(world)
    assert not k.objects["bowl"].localised and k.objects["bowl"].pose is not None
    plan = domain.plan_task(k, ("pour", "jar", "bowl"), "pour(jar,bowl)", with_safe_stops=False)
    place = world.placement("bowl", "table").positions[0]
    assert [a[0] for a in plan.actions] == ["a_face", "a_look", "a_perceive", "a_replan"]
    assert plan.actions[1][2] == place  # where the plan put it
    assert plan.actions[2][2] == "bowl"
