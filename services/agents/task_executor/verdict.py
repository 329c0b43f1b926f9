"""a_ta's decision on ag_ex's answer to the request of a leaf state (paper §5.5; the module
docstring of services/agents/task_executor/agent.py): go on to the next leaf, look again, or
observe the scene and report Replan; end the plan with Replan or Error; or, after a halt, make
the robot safe. :func:`judge` is a pure function of the leaf (:class:`Step`), ag_ex's
:class:`Answer` and whether a_ta is making the robot safe; a_ta only applies the
:class:`Verdict` it returns (``TaskExecutor._complete``).

The transitions, in the order they are tried:

=============================================  ===========================================
the leaf, the answer                           verdict
=============================================  ===========================================
ag_ex halted the command for a_ta's cancel     ``HALTED``
the observation after a surprise came          ``REPLAN`` with the surprise's reason
the first answer after the robot was power-   ``SURPRISE``: the plan may be of the
cycled (not in a safe stop)                    kitchen before
ag_ex's simulated time went back (not in a     ``SURPRISE``: the world went back
safe stop)
refuse, failure, not-understood, deadline:     ``SURPRISE`` (``interrupted``: ag_ex held
ag_ex held position, or a reason of            position), else ``ERROR`` with what ag_ex
:data:`REPLAN_FAILURES` (not in a safe stop)   said
the head turned for a second view              ``OBSERVE_AGAIN``
a Perceive's objects not where expected        ``ERROR`` when it ``judges``, else ``REPLAN``
(not in a safe stop)
an expected object's position too uncertain    ``LOOK`` at it the first time, then ``REPLAN``
too little content in a CheckContent's         ``LOOK`` at it the first time (when it was
container, the spheres seen and inferred       seen and not in a safe stop), then ``ERROR``
together
enough content only with the spheres inferred  ``LOOK`` at it the first time (likewise), then
behind its wall (too few seen)                 ``NEXT``, its reason saying the share rests on
                                               spheres no look saw
anything else                                  ``NEXT``
=============================================  ===========================================

A CheckContent's verdict carries in its ``reason`` (also for ``NEXT``: a_ta reports it with
Succeeded) how many spheres the deciding look saw and how many it inferred, and which look
decided (judge.py ``content_seen``). The goal stays the plan's share (``min_fraction``) of the
content. Seen spheres alone decide when they reach it; when only the inferred ones make it
reach the share, a second look is taken first, and of the two looks the one that saw more
spheres decides (``_deciding_look``). If it still sees too few, the task
succeeds on the inference and says so: from the head's height the bowl's near wall hides part
of its floor's ring when the bowl stands far enough away, whatever the torso's angle
(velma/perception/content.py ``count_spheres``; measured in docs/bench/observe.md), so failing
there would fail every full bowl.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import TYPE_CHECKING

import msgspec

from shared.fipa_codec.languages.common import Vec3
from shared.fipa_codec.languages.l_ex import NOT_AT_GRASP_POSE, CommandResult
from shared.fipa_codec.languages.l_hfsm import CheckContent, Perceive, PlanNode
from shared.fipa_codec.languages.l_sd import Observation

from .judge import content_counts, content_seen, content_shortfall, differences, seen_share, too_uncertain

if TYPE_CHECKING:
    from services.runtime.roles import Conversation

HELD = "held:"
"""Prefix of the reason ag_ex gives a command it ended to hold position (velma/executor/loop.py)."""
REPLAN_FAILURES = {
    "no contact": "the grasp closed on nothing",
    "contact lost": "the held object left the hand",
    "unreachable": "no arm configuration reaches the planned pose",
    NOT_AT_GRASP_POSE: "the hand was not at the grasp pose",
}
"""ag_ex failure reasons that mean the world may differ from the plan, and how a_ta says so:
a_ta observes the scene (a_km learns it) and reports Replan instead of Error. ``unreachable``:
the pose was planned from the objects as last seen, and a view that misplaced one (e.g. the
bowl under the held jar, seen right after ag_ex restarted) yields a pose no arm configuration
reaches; looking again and planning again is bounded by a_co's ``MAX_REPLANS_PER_TASK``.
``NOT_AT_GRASP_POSE``: ag_ex did not close a hand that is not where the plan put it (the
reach's target, ``Grasp.at``)."""


@dataclass
class Step:
    """The leaf state being executed: its HFSM path, node, and the C5 request awaiting reply."""

    path: str
    node: PlanNode
    waiting_for: Conversation | None = None
    reply: tuple[Conversation, bool] | None = None  # ag_ex's answer (inform: True) once it came
    replan_reason: str | None = None  # set on the observation made before reporting Replan
    second_view: int = 0  # 1: looking at an uncertain object or a short content again, 2: observed it again
    first_look: Observation | None = None  # what the first look saw, while a second view is taken
    halted: bool = False  # ag_ex answered a_ta's cancel: the command was halted
    went_back: tuple[float, float] | None = None  # (latest, answer's) simulated time, s: the world went back
    restarted: bool = False  # the robot was power-cycled since the plan was made (or may have been)


@dataclass(frozen=True)
class Answer:
    """ag_ex's answer to a leaf's request as :func:`judge` reads it: ``ok`` for ``inform``
    (else refuse, failure, not-understood or the runtime's passed reply-by deadline);
    ``content`` its L_EX/L_SD content (a ``CommandResult``, an ``Observation``) or None;
    ``said`` the performative's name (``failure`` for a passed deadline); ``reason`` its
    plain-text reason, or the performative's name (``Conversation.reason``)."""

    ok: bool
    content: msgspec.Struct | None
    said: str
    reason: str


class Do(enum.Enum):
    """What a_ta does after ag_ex answered a leaf's request (:class:`Verdict`)."""

    NEXT = "next"
    """The leaf is done: on to the next one."""
    LOOK = "look"
    """Turn the head to :attr:`Verdict.look_at` for a second view (``second_view`` 1)."""
    OBSERVE_AGAIN = "observe again"
    """The head turned: observe the leaf's objects again (``second_view`` 2)."""
    SURPRISE = "surprise"
    """The world differs from the plan: observe the whole scene (a_km learns it), then report
    Replan with :attr:`Verdict.reason`."""
    REPLAN = "replan"
    """End the plan: Replan, with :attr:`Verdict.reason`."""
    ERROR = "error"
    """End the plan: Error, with :attr:`Verdict.reason`."""
    HALTED = "halted"
    """ag_ex halted the command for a_ta's cancel: make the robot safe from where it stopped,
    then the safe stop (``TaskExecutor._after_halt``)."""


@dataclass(frozen=True)
class Verdict:
    """:func:`judge`'s decision: ``do``; ``reason`` in the words the person reads (for LOOK:
    why a second view; for a CheckContent's NEXT: what it counted, which a_ta reports with
    Succeeded); ``look_at`` the point the head turns to (LOOK; m, world); ``observed``
    the answer's observation, which a_km learns first (None: none to tell); ``interrupted``:
    ag_ex held position, so the leaf did not finish (a take is undone before the report);
    ``objects`` the objects to observe again (OBSERVE_AGAIN); ``notes`` what a_ta logs of it
    (the share of the content a CheckContent saw)."""

    do: Do
    reason: str | None = None
    look_at: Vec3 | None = None
    objects: tuple[str, ...] = ()
    observed: Observation | None = None
    interrupted: bool = False
    notes: tuple[str, ...] = ()


def judge(step: Step, answer: Answer, terminating: bool) -> Verdict:
    """a_ta's decision on ``answer``, ag_ex's answer to ``step``'s request, ``terminating``
    while a_ta runs a safe stop (its moves are not judged against the plan). Pure: reads its
    arguments, changes nothing (module docstring: the transitions)."""
    if step.halted:
        return Verdict(Do.HALTED)
    if step.replan_reason is not None:  # the observation made after a surprise
        observed = answer.content if isinstance(answer.content, Observation) else None
        return Verdict(Do.REPLAN, step.replan_reason, observed=observed)
    if step.restarted and not terminating:
        anew = "ag_ex's robot was power-cycled: its kitchen started anew (the plan may be of the one before)"
        return Verdict(Do.SURPRISE, f"{step.path}: {anew}")
    if step.went_back is not None and not terminating:
        latest, now = step.went_back
        went = f"ag_ex's world went back from {latest:.2f} s to {now:.2f} s (what was done may be undone)"
        return Verdict(Do.SURPRISE, f"{step.path}: {went}")
    if not answer.ok:
        return _failed(step.path, answer, terminating)
    return _done(step, answer, terminating)


def _failed(path: str, answer: Answer, terminating: bool) -> Verdict:
    """ag_ex did not do what leaf ``path`` asked: a surprise when the world may differ from
    the plan (not in a safe stop), else an error."""
    result = answer.content
    if isinstance(result, CommandResult) and not terminating:
        if (result.reason or "").startswith(HELD):
            # ag_ex stopped the motion because a_ta looked gone (a restart of a_ta or of
            # the router): where the robot got to is not known, so look and plan again
            return Verdict(Do.SURPRISE, f"{path}: ag_ex held position ({result.reason})", interrupted=True)
        if result.reason in REPLAN_FAILURES:
            return Verdict(Do.SURPRISE, f"{path}: {REPLAN_FAILURES[result.reason]}")
    reason = getattr(result, "reason", None) or answer.reason
    return Verdict(Do.ERROR, f"{path}: {answer.said}: {reason}")


def _done(step: Step, answer: Answer, terminating: bool) -> Verdict:
    """ag_ex did what the leaf asked (``inform``): a sensing leaf's observation is judged."""
    action = step.node.action
    if not isinstance(action, Perceive | CheckContent):
        return Verdict(Do.NEXT)
    if step.second_view == 1:  # the head turned to it: observe again
        objects = action.objects if isinstance(action, Perceive) else (action.container,)
        return Verdict(Do.OBSERVE_AGAIN, objects=objects)
    if not isinstance(answer.content, Observation):
        return Verdict(Do.NEXT)
    if isinstance(action, Perceive):
        return _perceived(step, action, answer.content, terminating)
    return _checked(step, action, answer.content, terminating)


def _perceived(step: Step, action: Perceive, obs: Observation, terminating: bool) -> Verdict:
    """A Perceive leaf's observation against what the plan expects (judge.py): where the
    objects are, how certain their positions."""
    if not action.expect or terminating:
        return Verdict(Do.NEXT, observed=obs)
    difference = differences(action, obs)
    if difference and action.judges:  # the world does not show the task done
        return Verdict(Do.ERROR, f"{step.path}: {difference}", observed=obs)
    uncertain = None if difference else too_uncertain(action, obs)
    if uncertain is not None and step.second_view == 0:
        name, where, _ = uncertain
        return Verdict(Do.LOOK, f"the {name}'s position is uncertain", look_at=where, observed=obs)
    if uncertain is not None:
        name, _, sigma = uncertain
        difference = f"the {name}'s position is too uncertain to grasp (σ {1e3 * sigma:.0f} mm)"
    if difference:
        return Verdict(Do.REPLAN, f"{step.path}: {difference}", observed=obs)
    return Verdict(Do.NEXT, observed=obs)


def _checked(step: Step, action: CheckContent, obs: Observation, terminating: bool) -> Verdict:
    """A CheckContent leaf's observation: the share of the content in its container, the
    spheres seen and those inferred behind its wall told apart (the module docstring)."""
    look, which = _deciding_look(step, action, obs)
    counted = content_seen(action, look, which)
    notes = (counted,)
    shortfall = content_shortfall(action, look)
    inferred_decide = not shortfall and seen_share(action, look) < action.min_fraction
    where = {o.name: o.pose.position for o in obs.objects}
    if (shortfall or inferred_decide) and _can_look(step, action.container in where, terminating):
        # one glimpse does not judge a task: the count can be one low (a sphere still
        # settling; docs/bench/observe.md) or rest on spheres inferred, not seen, so the head
        # turns to the container and the second look judges
        why = shortfall or _too_few_seen(action, obs)
        return Verdict(Do.LOOK, why, look_at=where[action.container], observed=obs, notes=notes)
    if shortfall:
        return Verdict(Do.ERROR, f"{shortfall}; {counted}", observed=obs, notes=notes)
    if inferred_decide:
        inferred = content_counts(action, look)[1]
        rests = f"the {100 * action.min_fraction:.0f} % rests on the {inferred} inferred, which no look saw"
        return Verdict(Do.NEXT, f"{counted}; {rests}", observed=obs, notes=notes)
    return Verdict(Do.NEXT, counted, observed=obs, notes=notes)


def _deciding_look(step: Step, action: CheckContent, obs: Observation) -> tuple[Observation, int]:
    """The look that judges a CheckContent, and its number: the first; after a second view,
    the one of the two that saw more spheres (the second on a tie). Nothing moved the content
    between them (the head only turned), so a sphere either look saw was seen, while each look
    can miss one whose top alone shows against the near wall (docs/bench/observe.md); the
    spheres a look inferred are never taken for seen ones."""
    first = step.first_look
    if step.second_view == 2 and first is not None and seen_share(action, first) > seen_share(action, obs):
        return first, 1
    return obs, 2 if step.second_view == 2 else 1


def _can_look(step: Step, seen: bool, terminating: bool) -> bool:
    """A second look is taken once, at a container that was ``seen``, not in a safe stop."""
    return step.second_view == 0 and seen and not terminating


def _too_few_seen(action: CheckContent, obs: Observation) -> str:
    """Why a second look, when the spheres inferred behind the wall decide, in words."""
    inside, inferred = content_counts(action, obs)
    return (
        f"only {inside - inferred} of {obs.total_particles} spheres seen in the "
        f"{action.container}, {inferred} more inferred behind its wall"
    )
