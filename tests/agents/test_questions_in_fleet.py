"""A person's question about the kitchen in the whole system, in one process on a MemoryBus
with a kinematic test double of the robot: a_ta's looks reach a_km with when a_ta received them,
and a_hi answers "what is in the bowl?" from a_km before and after a pour."""

from __future__ import annotations

import re

from services.runtime.human import ReportKind, RequestKind
from tests.support.fake_executor import PARTICLES
from tests.support.memory_fleet import MemoryFleet

AGE = r"(just now|\d+ s ago)"
"""How old a_hi says the knowledge is (a_ta's clock and a_hi's are the same here)."""


def test_what_is_in_the_bowl_before_and_after_a_pour() -> None:
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        (before,) = fleet.command("what is in the bowl?", "q1")
        pour = fleet.command("pour the jar into the bowl", "c1")
        (after,) = fleet.command("what's in the bowl now?", "q2")
        (jar,) = fleet.command("is the jar empty?", "q3")
    assert pour[-1].kind is ReportKind.SUCCEEDED, pour
    assert (before.kind, before.request) == (ReportKind.ANSWER, RequestKind.QUESTION)
    assert re.fullmatch(rf"The bowl held 0 spheres when I last looked, {AGE}: it was empty\.", before.text), (
        before
    )
    assert re.fullmatch(rf"The bowl held {PARTICLES} spheres when I last looked, {AGE}\.", after.text), after
    # the jar was not looked into after the pour (a_ta checks the bowl): its last count is told, with its age
    assert re.fullmatch(rf"No, the jar held {PARTICLES} spheres when I last looked, {AGE}\.", jar.text), jar
