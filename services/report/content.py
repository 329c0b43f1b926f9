"""The content outcome: how many of the jar's spheres ended in the bowl (the pour task of
paper §5.7; the paper reports no count, only "the content of the jar is poured into the bowl"
at 763 s)."""

from __future__ import annotations

from collections.abc import Sequence

from services.report.load import Message
from services.report.model import ContentOutcome
from shared.fipa_codec.languages.l_sd import Observation


def sphere_share(messages: Sequence[Message], container: str = "bowl") -> ContentOutcome:
    """From the last L_SD ``Observation`` (ag_ex → a_ta on C5, ``inform``) that reports
    ``particles_inside`` for ``container``: spheres inside, ``total_particles`` and their ratio."""
    for m in reversed(messages):
        if not m.is_("C5", "ag_ex", "inform") or not isinstance(m.content, Observation):
            continue
        for obj in m.content.objects:
            if obj.name == container and obj.particles_inside is not None:
                total = m.content.total_particles
                return ContentOutcome(
                    container=container,
                    observed=True,
                    inside=obj.particles_inside,
                    total=total,
                    share=obj.particles_inside / total if total > 0 else None,
                    t=m.t,
                    stamp=m.content.stamp,
                )
    return ContentOutcome(container=container, observed=False)
