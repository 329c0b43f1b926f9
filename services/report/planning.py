"""Planning phases (paper §5.7, Figure 13): each C3 plan request, a_pl's answer, and the
C4 traffic between them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from services.report.load import Message
from services.report.model import PlanPhase
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure

PLAN_ANSWERS = ("inform", "failure", "refuse")
"""Performatives by which a_pl ends a C3 plan request (an ``agree`` does not end it)."""

PEAK_BIN_S = 1.0
"""Width of the bins for the peak bandwidth (s); the paper's Figure 13 uses 1 s."""


def _end(
    messages: Sequence[Message], requests: list[tuple[int, Message]], n: int, answer: Message | None
) -> float:
    """When request ``n``'s phase ends: a_pl's answer, else the next request, else the last record."""
    if answer is not None:
        return answer.t
    if n + 1 < len(requests):
        return requests[n + 1][1].t
    return messages[-1].t


def _c4_figures(c4: list[Message], start: float, end: float) -> dict[str, Any]:
    """The C4 traffic of a phase from ``start`` to ``end``: count, bytes, queries, last, mean and
    peak bandwidth."""
    c4_bytes = sum(m.rec.size for m in c4)
    duration = end - start
    return {
        "c4_count": len(c4),
        "c4_bytes": c4_bytes,
        "c4_queries": sum(1 for m in c4 if m.performative == "query-ref"),
        "c4_last_t": c4[-1].t if c4 else None,
        # over at least one peak bin, so that a sub-second planning's mean stays ≤ its peak
        "mean_kbps": c4_bytes * 8 / 1000 / max(duration, PEAK_BIN_S) if c4 else None,
        "peak_kbps": _peak_kbps(c4, start),
    }


def _with_plan(phase: PlanPhase, plan: object) -> PlanPhase:
    """``phase`` with the figures of a_pl's plan, when the answer is one."""
    if isinstance(plan, HierarchicalPlan):
        phase.plan_id = plan.plan_id
        phase.km_queries = plan.km_queries
        phase.planning_time_s = plan.planning_time_s
        phase.complete = plan.complete
    return phase


def plan_phases(messages: Sequence[Message]) -> list[PlanPhase]:
    """One :class:`PlanPhase` per C3 ``request``, in order. C4 communicates are counted from
    the request to a_pl's answer (or, without one, to the next request or the last record)."""
    requests = [(i, m) for i, m in enumerate(messages) if m.is_("C3", None, "request")]
    phases: list[PlanPhase] = []
    for n, (pos, req) in enumerate(requests):
        answer = _answer(messages, pos, req)
        end = _end(messages, requests, n, answer)
        c4 = [m for m in messages if m.channel == "C4" and req.t <= m.t <= end]
        phase = PlanPhase(
            index=req.content.plan_index if isinstance(req.content, GroundTaskNetwork) else n + 1,
            requested_t=req.t,
            received_t=answer.t if answer is not None else None,
            **_c4_figures(c4, req.t, end),
            outcome=_outcome(answer),
        )
        phases.append(_with_plan(phase, answer.content if answer is not None else None))
    return phases


def _answer(messages: Sequence[Message], pos: int, req: Message) -> Message | None:
    for m in messages[pos + 1 :]:
        if (
            m.is_("C3", None, *PLAN_ANSWERS)
            and m.sender != req.sender
            and (req.conversation is None or m.conversation == req.conversation)
        ):
            return m
    return None


def _peak_kbps(c4: Sequence[Message], start: float) -> float | None:
    if not c4:
        return None
    bins: dict[int, int] = {}
    for m in c4:
        k = int((m.t - start) // PEAK_BIN_S)
        bins[k] = bins.get(k, 0) + m.rec.size
    return max(bins.values()) * 8 / 1000 / PEAK_BIN_S


def _outcome(answer: Message | None) -> str:
    if answer is None:
        return "no answer"
    content = answer.content
    if answer.performative == "inform":
        if isinstance(content, HierarchicalPlan):
            return "complete" if content.complete else "partial"
        return "received (content not decoded)"
    reason = content.reason if isinstance(content, PlanFailure) else answer.performative
    return f"failed: {reason}"
