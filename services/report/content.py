"""The content outcome: how many of the jar's spheres ended in the bowl (the pour task of
paper §5.7; the paper reports no count, only "the content of the jar is poured into the bowl"
at 763 s)."""

from __future__ import annotations

from collections.abc import Sequence

from services.report.load import Message
from services.report.model import ContentOutcome
from shared.fipa_codec.languages.l_ex import LookAt
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation


def _counted(m: Message, container: str) -> ObjectObservation | None:
    """``container`` in ``m`` when ``m`` is an L_SD ``Observation`` (ag_ex → a_ta on C5,
    ``inform``) that reports ``particles_inside`` for it, else None."""
    if not m.is_("C5", "ag_ex", "inform") or not isinstance(m.content, Observation):
        return None
    return next(
        (o for o in m.content.objects if o.name == container and o.particles_inside is not None), None
    )


def _look(messages: Sequence[Message], index: int, container: str) -> int:
    """Which look at ``container`` the observation ``messages[index]`` was: 2 when a_ta
    turned the head (an L_EX ``LookAt`` request on C5) since the observation before it that
    counted ``container``'s content (services/agents/task_executor/verdict.py: a second
    look), else 1."""
    for m in reversed(messages[:index]):
        if m.is_("C5", "a_ta", "request") and isinstance(m.content, LookAt):
            return 2
        if _counted(m, container) is not None:
            return 1
    return 1


def sphere_share(messages: Sequence[Message], container: str = "bowl") -> ContentOutcome:
    """From the last L_SD ``Observation`` (ag_ex → a_ta on C5, ``inform``) that reports
    ``particles_inside`` for ``container``: spheres inside, of them ``inferred`` (None: not
    split) and ``seen``, ``total_particles``, their ratio, and which look it was."""
    for i in range(len(messages) - 1, -1, -1):
        m = messages[i]
        obj = _counted(m, container)
        if obj is None or obj.particles_inside is None or not isinstance(m.content, Observation):
            continue
        total = m.content.total_particles
        inferred = obj.particles_inferred
        return ContentOutcome(
            container=container,
            observed=True,
            inside=obj.particles_inside,
            inferred=inferred,
            seen=obj.particles_inside - (inferred or 0),
            total=total,
            share=obj.particles_inside / total if total > 0 else None,
            t=m.t,
            stamp=m.content.stamp,
            look=_look(messages, i, container),
        )
    return ContentOutcome(container=container, observed=False)


def content_line(c: ContentOutcome, world: tuple[int, int] | None = None) -> str:
    """The content outcome in the few words `roco run`'s last line gives it, saying whose count
    it is: the robot's (``c``, a_ta's last count of the container, the seen and the inferred
    spheres) and beside it, when given, the simulation's (``world``: the spheres truly in the
    container as the simulated world was left, and the content's total; services/scenario/
    chaos.py ``world_content``). E.g. "18 of 18 spheres in the bowl by the robot's count (the
    simulation's: 18)", "18 of 18 spheres in the bowl by the robot's count", "content not
    observed by the robot (the simulation's: 17 of 18 in the bowl)"."""
    if c.observed:
        robot = f"{c.inside} of {c.total} spheres in the {c.container} by the robot's count"
        return robot if world is None else f"{robot} (the simulation's: {world[0]})"
    if world is None:
        return "content not observed by the robot"
    return (
        f"content not observed by the robot (the simulation's: {world[0]} of {world[1]} in the {c.container})"
    )
