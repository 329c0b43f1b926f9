"""a_ta's decision on ag_ex's answer to a leaf's request (services/agents/task_executor/verdict.py
``judge``), case by case: a pure function of the leaf, the answer and whether a_ta runs a safe
stop — no agent, no process."""

from __future__ import annotations

import msgspec
import pytest

from services.agents.task_executor.verdict import Answer, Do, Step, Verdict, judge
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import NOT_AT_GRASP_POSE, CommandResult, Wait
from shared.fipa_codec.languages.l_hfsm import CheckContent, Execute, ExpectedPosition, Perceive, PlanNode
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from velma.scenario import BOWL_PLACE_POSITION

PLACED = BOWL_PLACE_POSITION
ELSEWHERE = (PLACED[0], PLACED[1] + 0.10, PLACED[2])
"""10 cm from the bowl's place."""
WAIT = Execute(command=Wait(duration=1.0))
CHECK = CheckContent(container="bowl", min_fraction=0.9)


def step(
    action: Execute | Perceive | CheckContent = WAIT,
    *,
    replan_reason: str | None = None,
    second_view: int = 0,
    halted: bool = False,
    went_back: tuple[float, float] | None = None,
    restarted: bool = False,
) -> Step:
    node = PlanNode(name="wait", action=action)
    return Step(
        "pour/wait",
        node,
        replan_reason=replan_reason,
        second_view=second_view,
        halted=halted,
        went_back=went_back,
        restarted=restarted,
    )


def done(content: msgspec.Struct | None = None) -> Answer:
    return Answer(True, content, "inform", "inform")


def failed(reason: str | None, said: str = "failure") -> Answer:
    result = CommandResult(command="wait", ok=False, reason=reason)
    return Answer(False, result, said, reason or said)


def seen(*objects: ObjectObservation) -> Observation:
    return Observation(stamp=1.0, objects=objects, total_particles=18)


def bowl(
    position: tuple[float, float, float] = PLACED,
    inside: int | None = 18,
    sigma: float | None = None,
    inferred: int | None = None,
) -> ObjectObservation:
    return ObjectObservation(
        name="bowl",
        pose=Pose(position),
        particles_inside=inside,
        position_sigma=sigma,
        particles_inferred=inferred,
    )


def perceive(judges: bool = False, max_sigma: float | None = None) -> Perceive:
    expect = ExpectedPosition(object="bowl", position=PLACED, max_sigma=max_sigma)
    return Perceive(objects=("bowl",), expect=(expect,), judges=judges)


def test_a_done_command_goes_on_to_the_next_leaf() -> None:
    assert judge(step(), done(CommandResult(command="wait", ok=True)), False) == Verdict(Do.NEXT)


def test_a_halted_command_makes_the_robot_safe_whatever_the_answer() -> None:
    assert judge(step(halted=True), failed("halted"), False).do is Do.HALTED


def test_the_observation_after_a_surprise_ends_the_plan_in_replan_and_reaches_a_km() -> None:
    obs = seen(bowl())
    v = judge(step(replan_reason="pour/wait: the grasp closed on nothing"), done(obs), False)
    assert v == Verdict(Do.REPLAN, "pour/wait: the grasp closed on nothing", observed=obs)
    # no observation (its deadline passed): the reason is reported all the same, a_km learns nothing
    v = judge(step(replan_reason="r"), Answer(False, None, "failure", "reply-by deadline passed"), False)
    assert v == Verdict(Do.REPLAN, "r")


def test_a_world_that_went_back_is_a_surprise_except_in_a_safe_stop() -> None:
    v = judge(step(went_back=(12.5, 3.25)), done(), False)
    assert v.do is Do.SURPRISE
    assert (
        v.reason == "pour/wait: ag_ex's world went back from 12.50 s to 3.25 s (what was done may be undone)"
    )
    assert judge(step(went_back=(12.5, 3.25)), done(), True).do is Do.NEXT


def test_an_answer_from_a_world_started_anew_is_a_surprise_except_in_a_safe_stop() -> None:
    v = judge(step(restarted=True), done(), False)
    assert v == Verdict(
        Do.SURPRISE,
        "pour/wait: ag_ex's robot was power-cycled: its kitchen started anew "
        "(the plan may be of the one before)",
    )
    assert judge(step(restarted=True), done(), True).do is Do.NEXT


def test_held_position_is_a_surprise_of_an_unfinished_leaf() -> None:
    v = judge(step(), failed("held: a_ta is gone"), False)
    assert v == Verdict(Do.SURPRISE, "pour/wait: ag_ex held position (held: a_ta is gone)", interrupted=True)


@pytest.mark.parametrize(
    ("reason", "said"),
    [
        ("no contact", "the grasp closed on nothing"),
        ("contact lost", "the held object left the hand"),
        ("unreachable", "no arm configuration reaches the planned pose"),
        (NOT_AT_GRASP_POSE, "the hand was not at the grasp pose"),
    ],
)
def test_a_failure_that_says_the_world_differs_is_a_surprise(reason: str, said: str) -> None:
    assert judge(step(), failed(reason), False) == Verdict(Do.SURPRISE, f"pour/wait: {said}")


def test_in_a_safe_stop_every_failure_is_an_error() -> None:
    assert judge(step(), failed("no contact"), True) == Verdict(Do.ERROR, "pour/wait: failure: no contact")
    assert judge(step(), failed("held: gone"), True).do is Do.ERROR


def test_any_other_failure_is_an_error_naming_what_ag_ex_said() -> None:
    assert judge(step(), failed("timeout"), False) == Verdict(Do.ERROR, "pour/wait: failure: timeout")
    refused = Answer(False, None, "refuse", "busy")
    assert judge(step(), refused, False) == Verdict(Do.ERROR, "pour/wait: refuse: busy")
    deadline = Answer(False, None, "failure", "reply-by deadline passed")
    assert judge(step(), deadline, False).reason == "pour/wait: failure: reply-by deadline passed"


def test_after_the_head_turned_the_leaf_observes_its_objects_again() -> None:
    look_done = done(CommandResult(command="look_at", ok=True))
    assert judge(step(perceive(), second_view=1), look_done, False) == Verdict(
        Do.OBSERVE_AGAIN, objects=("bowl",)
    )
    assert judge(step(CHECK, second_view=1), look_done, False).objects == ("bowl",)


def test_a_perceive_that_sees_what_the_plan_expects_goes_on() -> None:
    obs = seen(bowl())
    assert judge(step(perceive()), done(obs), False) == Verdict(Do.NEXT, observed=obs)


def test_an_object_elsewhere_is_a_replan_or_when_it_judges_the_task_an_error() -> None:
    obs = seen(bowl(ELSEWHERE))
    difference = "pour/wait: the bowl is 10 cm from where the plan expects it"
    assert judge(step(perceive()), done(obs), False) == Verdict(Do.REPLAN, difference, observed=obs)
    assert judge(step(perceive(judges=True)), done(obs), False) == Verdict(Do.ERROR, difference, observed=obs)


def test_in_a_safe_stop_a_perceive_only_informs_a_km() -> None:
    obs = seen(bowl(ELSEWHERE))
    assert judge(step(perceive(judges=True)), done(obs), True) == Verdict(Do.NEXT, observed=obs)


def test_an_uncertain_position_is_looked_at_once_then_replanned() -> None:
    obs = seen(bowl(sigma=0.02))
    first = judge(step(perceive(max_sigma=0.005)), done(obs), False)
    assert first == Verdict(Do.LOOK, "the bowl's position is uncertain", look_at=PLACED, observed=obs)
    again = judge(step(perceive(max_sigma=0.005), second_view=2), done(obs), False)
    assert again == Verdict(
        Do.REPLAN, "pour/wait: the bowl's position is too uncertain to grasp (σ 20 mm)", observed=obs
    )


def test_a_content_check_that_passes_goes_on_and_says_what_it_saw() -> None:
    obs = seen(bowl(inside=17))
    counted = "the bowl holds 17 of 18 spheres, all seen (94 %), at the first look"
    assert judge(step(CHECK), done(obs), False) == Verdict(Do.NEXT, counted, observed=obs, notes=(counted,))


def test_a_short_content_is_looked_at_once_then_an_error() -> None:
    obs = seen(bowl(inside=10))
    shortfall = "bowl holds only 56 % of the content (needs 90 %)"
    first = "the bowl holds 10 of 18 spheres, all seen (56 %), at the first look"
    second = first.replace("first", "second")
    assert judge(step(CHECK), done(obs), False) == Verdict(
        Do.LOOK, shortfall, look_at=PLACED, observed=obs, notes=(first,)
    )
    assert judge(step(CHECK, second_view=2), done(obs), False) == Verdict(
        Do.ERROR, f"{shortfall}; {second}", observed=obs, notes=(second,)
    )
    # in a safe stop, or with the container not seen, there is no second view
    assert judge(step(CHECK), done(obs), True).do is Do.ERROR
    assert judge(step(CHECK), done(seen()), False).do is Do.ERROR


def test_when_the_inferred_spheres_decide_the_second_look_judges_on_what_it_saw() -> None:
    # the first look saw 15 of 18 (83 %) and inferred 3 behind the wall: the inferred decide
    first = seen(bowl(inside=18, inferred=3))
    look = judge(step(CHECK), done(first), False)
    assert look.do is Do.LOOK and look.look_at == PLACED
    assert look.reason == "only 15 of 18 spheres seen in the bowl, 3 more inferred behind its wall"
    # the head turned to the bowl: it is observed again, and that look judges
    assert judge(step(CHECK, second_view=1), done(None), False) == Verdict(
        Do.OBSERVE_AGAIN, objects=("bowl",)
    )
    better = seen(bowl(inside=18, inferred=1))
    counted = (
        "the bowl holds 18 of 18 spheres, 17 seen (94 %) and 1 inferred behind its wall, at the second look"
    )
    assert judge(step(CHECK, second_view=2), done(better), False) == Verdict(
        Do.NEXT, counted, observed=better, notes=(counted,)
    )
    # the second look seeing no more: the task succeeds on the inference, and says so
    still = judge(step(CHECK, second_view=2), done(first), False)
    assert still.do is Do.NEXT
    assert still.reason == (
        "the bowl holds 18 of 18 spheres, 15 seen (83 %) and 3 inferred behind its wall, at the second look; "
        "the 90 % rests on the 3 inferred, which no look saw"
    )
    # seen and inferred together short: a look, then an error, as for a short count
    short = seen(bowl(inside=16, inferred=3))
    assert judge(step(CHECK), done(short), False).do is Do.LOOK
    assert judge(step(CHECK, second_view=2), done(short), False).do is Do.ERROR


def test_after_a_second_look_the_look_that_saw_more_decides() -> None:
    # 17 in the bowl: the first look saw 16 (89 %) and inferred 1; the second, from the turned
    # head, missed one more against the near wall (15 + 1: 89 % even with the inferred)
    first = seen(bowl(inside=17, inferred=1))
    assert judge(step(CHECK), done(first), False).do is Do.LOOK
    second = seen(bowl(inside=16, inferred=1))
    again = step(CHECK, second_view=2)
    assert judge(again, done(second), False).do is Do.ERROR  # the second look alone
    again.first_look = first
    verdict = judge(again, done(second), False)
    assert verdict.do is Do.NEXT
    assert verdict.reason == (
        "the bowl holds 17 of 18 spheres, 16 seen (89 %) and 1 inferred behind its wall, at the first look; "
        "the 90 % rests on the 1 inferred, which no look saw"
    )
    assert verdict.observed == second  # a_km learns the latest look
    # a second look that saw more decides, and one that saw as many: the later one
    assert judge(again, done(seen(bowl(inside=17, inferred=0))), False).reason == (
        "the bowl holds 17 of 18 spheres, all seen (94 %), at the second look"
    )
    tie = judge(again, done(first), False).reason or ""
    assert tie.endswith("at the second look; the 90 % rests on the 1 inferred, which no look saw")


def test_a_sensing_leaf_answered_without_an_observation_goes_on() -> None:
    assert judge(step(perceive()), done(None), False) == Verdict(Do.NEXT)
