"""Commands and their coordination (paper Table 3 and Figure 8): every human command on C2
with its priority and outcome, and the coordinate-protocol exchange on C1 that starts,
cancels and ends plans (request, cancel, Terminating, Preempted, Replan, Succeeded, Error)."""

from __future__ import annotations

from collections.abc import Sequence

from services.report.load import Message
from services.report.model import CommandRow, CoordinationEvent
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan
from shared.fipa_codec.languages.l_sw import SWState, SWStatus

_SHOWN_STATES = frozenset(
    {SWState.TERMINATING, SWState.PREEMPTED, SWState.REPLAN, SWState.SUCCEEDED, SWState.ERROR}
)


def commands(messages: Sequence[Message]) -> list[CommandRow]:
    """One row per C2 command conversation, in order of the request."""
    rows: dict[str, CommandRow] = {}
    for m in messages:
        if m.channel != "C2" or m.conversation is None:
            continue
        if m.performative == "request" and isinstance(m.content, HumanCommand):
            rows[m.conversation] = CommandRow(
                conversation=m.conversation, text=m.content.text, priority=m.content.priority, requested_t=m.t
            )
        row = rows.get(m.conversation)
        if row is None:
            continue
        if m.performative == "cancel":
            row.cancelled_t = m.t
        elif m.sender == "a_co" and isinstance(m.content, CommandOutcome):
            row.ended_t = m.t
            stopped = row.cancelled_t is not None and not m.content.succeeded
            row.outcome = "stopped" if stopped else "succeeded" if m.content.succeeded else "failed"
            row.detail = m.content.detail
        elif m.sender == "a_co" and m.performative in ("failure", "refuse") and row.outcome is None:
            row.ended_t = m.t
            row.outcome = "failed"
            row.detail = m.comm.content.decode("utf-8", "replace") if m.comm is not None else ""
    return list(rows.values())


def coordination(messages: Sequence[Message]) -> list[CoordinationEvent]:
    """The C1 exchanges that change what the robot does: plan requests, cancels, and a_ta's
    Terminating, Preempted, Replan, Succeeded and Error informs (with a_co's confirmations
    folded in)."""
    out: list[CoordinationEvent] = []
    terminating: set[str | None] = set()  # a_ta informs Terminating at every safe-stop step
    for m in messages:
        if m.channel != "C1":
            continue
        who = f"{m.sender} → {m.rec.receivers[0] if m.rec.receivers else '?'}"
        if m.performative == "request" and isinstance(m.content, HierarchicalPlan):
            text = f"run plan {m.content.plan_id} ({len(m.content.root.leaves())} steps)"
        elif m.performative == "cancel":
            reason = m.content.reason if isinstance(m.content, SWStatus) and m.content.reason else ""
            text = f"cancel: {reason}" if reason else "cancel"
        elif (
            m.performative == "inform"
            and isinstance(m.content, SWStatus)
            and m.content.state in _SHOWN_STATES
        ):
            if m.content.state is SWState.TERMINATING:
                if m.conversation in terminating:
                    continue
                terminating.add(m.conversation)
            step = f" at {m.content.step}" if m.content.step else ""
            reason = f": {m.content.reason}" if m.content.reason else ""
            text = f"{m.content.state.value}{step}{reason}"
        else:
            continue
        out.append(
            CoordinationEvent(
                t=m.t, who=who, performative=m.performative, text=text, conversation=m.conversation
            )
        )
    return out
