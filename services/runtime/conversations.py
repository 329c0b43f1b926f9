"""Conversation tracking: pending replies identified by reply-with, and reply-by deadlines.

When an agent sends a communicate with ``reply_with`` and ``reply_by``, it waits for a reply
whose ``in-reply-to`` matches. If the deadline passes first, the runtime places a local
``failure`` (reason ``reply-by deadline passed``) in the agent's input buffer, so every
conversation ends (FIPA SC00061 §2.4: reply-by).
"""

from __future__ import annotations

from dataclasses import dataclass

FINAL_REPLIES = frozenset(
    {"inform", "inform-ref", "inform-if", "failure", "refuse", "not-understood", "disconfirm", "confirm"}
)
"""Performatives that answer a request or query for good; ``agree`` only acknowledges."""


@dataclass
class Pending:
    """A communicate awaiting a reply: its ``reply_with``, peer, protocol, conversation and
    the POSIX time ``deadline`` (None: no deadline)."""

    reply_with: str
    peer: str
    protocol: str | None
    conversation_id: str | None
    deadline: float | None
    streaming: bool = False  # subscribe/coordinate: many replies, never final by itself


class Conversations:
    """Pending replies of one agent, keyed by reply-with."""

    def __init__(self) -> None:
        self._pending: dict[str, Pending] = {}

    def expect(self, pending: Pending) -> None:
        self._pending[pending.reply_with] = pending

    def answered(self, in_reply_to: str | None, performative: str) -> Pending | None:
        """Note a reply; returns the pending entry it answers (None if unknown). A final reply
        ends the wait; ``agree`` or a streaming reply keeps it."""
        if in_reply_to is None:
            return None
        entry = self._pending.get(in_reply_to)
        if entry is None:
            return None
        if performative in FINAL_REPLIES and not entry.streaming:
            del self._pending[in_reply_to]
        elif entry.streaming:
            entry.deadline = None  # a live stream has answered; its deadline no longer applies
        return entry

    def knows(self, in_reply_to: str | None) -> bool:
        return in_reply_to is not None and in_reply_to in self._pending

    def forget(self, reply_with: str) -> None:
        self._pending.pop(reply_with, None)

    def forget_conversation(self, conversation_id: str) -> None:
        """Stop waiting for any reply in conversation ``conversation_id``."""
        for key in [k for k, p in self._pending.items() if p.conversation_id == conversation_id]:
            del self._pending[key]

    def expired(self, now: float) -> list[Pending]:
        """Remove and return the entries whose deadline has passed."""
        out = [p for p in self._pending.values() if p.deadline is not None and p.deadline <= now]
        for p in out:
            del self._pending[p.reply_with]
        return out

    def next_deadline(self) -> float | None:
        times = [p.deadline for p in self._pending.values() if p.deadline is not None]
        return min(times) if times else None

    def __len__(self) -> int:
        return len(self._pending)
