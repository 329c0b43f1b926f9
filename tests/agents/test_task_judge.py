"""a_ta's judgements of the observed world (services/agents/task_executor/judge.py): an object
not where the plan put it, not upright, too uncertain to grasp, and a container holding too
little of the content — with the reason the person reads."""

from __future__ import annotations

import math

from services.agents.task_executor.judge import (
    content_seen,
    content_share,
    content_shortfall,
    differences,
    seen_share,
    too_uncertain,
)
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_hfsm import CheckContent, ExpectedPosition, Perceive
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from velma.scenario import BOWL_PLACE_POSITION

PLACED = BOWL_PLACE_POSITION
ELSEWHERE = (PLACED[0], PLACED[1] + 0.10, PLACED[2])
"""10 cm from the bowl's place."""
CHECK = CheckContent(container="bowl", min_fraction=0.9)


def seen(*objects: ObjectObservation, outside: int | None = None) -> Observation:
    return Observation(stamp=1.0, objects=objects, total_particles=18, particles_outside=outside)


def bowl(
    position: tuple[float, float, float] = PLACED, inside: int | None = 18, **kw: object
) -> ObjectObservation:
    return ObjectObservation(name="bowl", pose=Pose(position), particles_inside=inside, **kw)  # type: ignore[arg-type]


def test_the_content_check_passes_at_the_share_and_fails_below_it() -> None:
    assert content_share(CHECK, seen(bowl(inside=17))) == 17 / 18
    assert content_shortfall(CHECK, seen(bowl(inside=17))) == ""
    assert (
        content_shortfall(CHECK, seen(bowl(inside=16))) == "bowl holds only 89 % of the content (needs 90 %)"
    )
    assert content_shortfall(CHECK, seen()).startswith("bowl holds only 0 %")  # the bowl not seen


def test_the_reason_names_the_content_seen_outside() -> None:
    reason = content_shortfall(CHECK, seen(bowl(inside=15), outside=3))
    assert reason == "bowl holds only 83 % of the content (needs 90 %); 3 of 18 seen outside it"
    assert "outside" not in content_shortfall(CHECK, seen(bowl(inside=15), outside=0))


def test_a_placed_object_elsewhere_or_leaning_is_a_difference() -> None:
    expect = Perceive(
        objects=("bowl",), expect=(ExpectedPosition(object="bowl", position=PLACED, max_tilt=0.2),)
    )
    assert differences(expect, seen(bowl())) == ""
    assert differences(expect, seen(bowl(ELSEWHERE))) == "the bowl is 10 cm from where the plan expects it"
    assert differences(expect, seen()) == "the bowl was not seen"
    s = math.sin(math.pi / 4)
    fallen = ObjectObservation(name="bowl", pose=Pose(PLACED, (s, s, 0.0, 0.0)))
    assert differences(expect, seen(fallen)) == "the bowl is not upright: it leans 90°"


def test_a_position_too_uncertain_for_the_grasp_is_named() -> None:
    expect = Perceive(
        objects=("bowl",), expect=(ExpectedPosition(object="bowl", position=PLACED, max_sigma=0.005),)
    )
    assert too_uncertain(expect, seen(bowl(position_sigma=0.002))) is None
    assert too_uncertain(expect, seen(bowl(position_sigma=0.02))) == ("bowl", PLACED, 0.02)


def test_the_count_in_words_tells_seen_from_inferred() -> None:
    assert content_seen(CHECK, seen(bowl(inside=18, particles_inferred=3)), 2) == (
        "the bowl holds 18 of 18 spheres, 15 seen (83 %) and 3 inferred behind its wall, at the second look"
    )
    assert content_seen(CHECK, seen(bowl(inside=17)), 1) == (
        "the bowl holds 17 of 18 spheres, all seen (94 %), at the first look"
    )
    assert content_seen(CHECK, seen(), 1) == "the bowl was not seen at the first look"
    assert seen_share(CHECK, seen(bowl(inside=18, particles_inferred=3))) == 15 / 18
