"""Progress lines for a person watching a run: selected communicates, in words.

Reads the same traffic the recorder sees (``roco/fipa/**``) and names the events of paper
Table 7: the command, plan requests and plans, a_ta's L_SW states and plan steps, executor
failures, observations sent to a_km, and the outcome.
"""

from __future__ import annotations

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
    perf = msg.performative
    head = f"{channel} {sender} → {receiver}"
    if isinstance(content, HumanCommand):
        return f"{head}: request “{content.text}”"
    if isinstance(content, GroundTaskNetwork):
        return f"{head}: plan #{content.plan_index} requested"
    if isinstance(content, HierarchicalPlan):
        kind = "complete" if content.complete else "partial, ends with sensing"
        return (
            f"{head}: plan {content.plan_id}: {len(content.root.leaves())} steps ({kind}), "
            f"{content.km_queries} a_km queries, {content.planning_time_s:.2f} s"
        )
    if isinstance(content, PlanFailure):
        return f"{head}: no plan: {content.reason}"
    if isinstance(content, SWStatus):
        extra = f" {content.step}" if content.step else ""
        reason = f" ({content.reason})" if content.reason else ""
        return f"{head}: {content.state.value}{extra}{reason}"
    if isinstance(content, CommandResult) and not content.ok:
        return f"{head}: {content.command} failed: {content.reason}"
    if isinstance(content, WorldUpdate) and any(o.pose is not None for o in content.objects):
        seen = ", ".join(o.name for o in content.objects if o.pose is not None)
        return f"{head}: observation at t={content.stamp:.1f} s ({seen})"
    if isinstance(content, CommandOutcome):
        return f"{head}: {'succeeded' if content.succeeded else 'failed'}: {content.detail}"
    if perf is Performative.NOT_UNDERSTOOD:
        return f"{head}: not-understood: {msg.content.decode('utf-8', 'replace')}"
    return None


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
