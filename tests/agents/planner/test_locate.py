"""A pour whose jar or bowl a_km has never seen (its picture renewed after a power cycle from
an observation made facing the table, where the fresh kitchen has nothing) observes the scene,
then looks into the cabinet, where a fresh kitchen keeps them, before it plans again: observing
only where the head looks found nothing seven times over."""

from __future__ import annotations

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.domain import plan_task
from tests.agents.planner.kitchen import knowledge as kitchen_knowledge


def test_objects_never_seen_are_looked_for_in_the_cabinet() -> None:
    k = kitchen_knowledge(WorldModel(), ("table", "cabinet"))
    assert k.objects["jar"].pose is None and k.objects["bowl"].pose is None
    result = plan_task(k, ("pour", "jar", "bowl"), "pour(jar,bowl)")
    steps = [(a[0], a[1].rsplit("/", 1)[-1]) for a in result.actions]
    assert steps[0] == ("a_perceive", "observe_scene") and steps[-1] == ("a_replan", "replan")
    look = steps.index(("a_look", "look_at_cabinet"))
    assert ("a_face", "face_cabinet") in steps[look:] and steps[-2] == ("a_perceive", "observe_cabinet")
    (view,) = [a[2] for a in result.actions if a[0] == "a_look"]
    assert view == k.objects["cabinet"].view_point
