"""Progress lines for a person watching a run: selected communicates, in words.

Reads the same traffic the recorder sees (``roco/fipa/**``) and names the events of paper
Table 7: the command, plan requests and plans, a_ta's L_SW states and plan steps, executor
failures, observations sent to a_km, and the outcome.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from services.runtime import keys
from shared.fipa_codec import DecodeError, Performative, decode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.languages.l_wm import WorldUpdate


def progress_line(key: str, payload: bytes) -> str | None:
    """One line describing the communicate, or None when it is not worth a line."""
    try:
        channel, sender, receiver = keys.parse_fipa_key(key)
        msg = decode(payload)
    except (ValueError, DecodeError):
        return None
    try:
        content = decode_content(msg.language, msg.content) if msg.content and msg.language else None
    except ContentError:
        content = None
    head = f"{channel} {sender} → {receiver}"
    for kind, line in _LINES:
        if isinstance(content, kind) and (said := line(content)) is not None:
            return f"{head}: {said}"
    if msg.performative is Performative.NOT_UNDERSTOOD:
        return f"{head}: not-understood: {msg.content.decode('utf-8', 'replace')}"
    return None


def _plan(content: HierarchicalPlan) -> str:
    kind = "complete" if content.complete else "partial, ends with sensing"
    return (
        f"plan {content.plan_id}: {len(content.root.leaves())} steps ({kind}), "
        f"{content.km_queries} a_km queries, {content.planning_time_s:.2f} s"
    )


def _status(content: SWStatus) -> str:
    extra = f" {content.step}" if content.step else ""
    reason = f" ({content.reason})" if content.reason else ""
    return f"{content.state.value}{extra}{reason}"


def _failed(content: CommandResult) -> str | None:
    return None if content.ok else f"{content.command} failed: {content.reason}"


def _observation(content: WorldUpdate) -> str | None:
    if not any(o.pose is not None for o in content.objects):
        return None
    seen = ", ".join(o.name for o in content.objects if o.pose is not None)
    return f"observation at t={content.stamp:.1f} s ({seen})"


_LINES: tuple[tuple[type, Callable[[Any], str | None]], ...] = (
    (HumanCommand, lambda c: f"request “{c.text}”"),
    (GroundTaskNetwork, lambda c: f"plan #{c.plan_index} requested"),
    (HierarchicalPlan, _plan),
    (PlanFailure, lambda c: f"no plan: {c.reason}"),
    (SWStatus, _status),
    (CommandResult, _failed),
    (WorldUpdate, _observation),
    (CommandOutcome, lambda c: f"{'succeeded' if c.succeeded else 'failed'}: {c.detail}"),
)
"""What a line says after its head (channel, sender → receiver) for a content of each kind, in
this order; None: no line for it (the not-understood line may still come)."""


def is_world_update(payload: bytes) -> bool:
    """True when ``payload`` is an inform carrying an L_WM WorldUpdate (an observation), or a
    batch (shared/fipa_codec/batch.py) holding one."""
    for part in unpack(payload):
        try:
            msg = decode(part)
            if msg.performative is Performative.INFORM and isinstance(
                decode_content(msg.language, msg.content), WorldUpdate
            ):
                return True
        except (DecodeError, ContentError):
            continue
    return False
