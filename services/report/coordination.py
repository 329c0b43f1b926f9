"""Commands and their coordination (paper Table 3 and Figure 8): every human command on C2
with its priority and outcome, and the coordinate-protocol exchange on C1 that starts,
cancels and ends plans (request, cancel, Terminating, Preempted, Replan, Succeeded, Error)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from services.recorder.causal import causal_order, send_order
from services.report.load import Message
from services.report.model import CommandRow, CoordinationEvent
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan
from shared.fipa_codec.languages.l_sw import SWState, SWStatus

_SHOWN_STATES = frozenset(
    {SWState.TERMINATING, SWState.PREEMPTED, SWState.REPLAN, SWState.SUCCEEDED, SWState.ERROR}
)


def _outcome(row: CommandRow, m: Message) -> None:
    """a_co's CommandOutcome ``m`` ends the command: stopped (after a cancel, unsuccessful),
    succeeded or failed."""
    assert isinstance(m.content, CommandOutcome)
    row.ended_t = m.t
    stopped = row.cancelled_t is not None and not m.content.succeeded
    row.outcome = "stopped" if stopped else "succeeded" if m.content.succeeded else "failed"
    row.detail = m.content.detail


def _refused(row: CommandRow, m: Message) -> None:
    """a_co's failure or refuse ``m`` ends the command as failed, its reason the detail."""
    row.ended_t = m.t
    row.outcome = "failed"
    row.detail = m.comm.content.decode("utf-8", "replace") if m.comm is not None else ""


def _cancelled(row: CommandRow, m: Message) -> None:
    row.cancelled_t = m.t


def _command_rule(row: CommandRow, m: Message) -> Callable[[CommandRow, Message], None] | None:
    """What ``m`` does to its command's row, the first rule that applies: a cancel, a_co's
    outcome, a_co's failure or refuse (unless an outcome came first); None: nothing."""
    if m.performative == "cancel":
        return _cancelled
    if m.sender != "a_co":
        return None
    if isinstance(m.content, CommandOutcome):
        return _outcome
    if m.performative in ("failure", "refuse") and row.outcome is None:
        return _refused
    return None


def _plan_text(plan: HierarchicalPlan) -> str:
    return f"run plan {plan.plan_id} ({len(plan.root.leaves())} steps)"


def _cancel_text(m: Message) -> str:
    reason = m.content.reason if isinstance(m.content, SWStatus) and m.content.reason else ""
    return f"cancel: {reason}" if reason else "cancel"


def _status_text(status: SWStatus) -> str:
    step = f" at {status.step}" if status.step else ""
    reason = f": {status.reason}" if status.reason else ""
    return f"{status.state.value}{step}{reason}"


@dataclass
class _Coordination:
    """The C1 record replayed message by message (:meth:`text`): what each exchange shows, or
    None when it is not shown; a_ta's Terminating is shown once per conversation (it informs
    Terminating at every safe-stop step)."""

    terminating: set[str | None] = field(default_factory=set)

    def text(self, m: Message) -> str | None:
        if m.performative == "request" and isinstance(m.content, HierarchicalPlan):
            return _plan_text(m.content)
        if m.performative == "cancel":
            return _cancel_text(m)
        if (
            m.performative == "inform"
            and isinstance(m.content, SWStatus)
            and m.content.state in _SHOWN_STATES
        ):
            return self.status(m.conversation, m.content)
        return None

    def status(self, conversation: str | None, status: SWStatus) -> str | None:
        if status.state is SWState.TERMINATING:
            if conversation in self.terminating:
                return None
            self.terminating.add(conversation)
        return _status_text(status)


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
        rule = _command_rule(row, m) if row is not None else None
        if row is not None and rule is not None:
            rule(row, m)
    return list(rows.values())


def coordination(messages: Sequence[Message]) -> list[CoordinationEvent]:
    """The C1 exchanges that change what the robot does: plan requests, cancels, and a_ta's
    Terminating, Preempted, Replan, Succeeded and Error informs (with a_co's confirmations
    folded in), in causal order (causal.py: agents linked directly reach the recorder on
    different paths, so a_ta's Terminating can be recorded before a_co's cancel)."""
    out: list[CoordinationEvent] = []
    replay = _Coordination()
    c1 = [m for m in messages if m.channel == "C1"]
    for m in send_order(causal_order(c1)[0])[0]:
        text = replay.text(m)
        if text is None:
            continue
        who = f"{m.sender} → {m.rec.receivers[0] if m.rec.receivers else '?'}"
        out.append(
            CoordinationEvent(
                t=m.t, who=who, performative=m.performative, text=text, conversation=m.conversation
            )
        )
    return out
