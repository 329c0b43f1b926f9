"""The replies an agent awaits: reply-by deadlines, and retransmission until the first answer.

When an agent sends a communicate with ``reply_with`` and ``reply_by``, it waits for a reply
whose ``in-reply-to`` matches. If the deadline passes first, the runtime places a local
``failure`` (reason ``reply-by deadline passed``) in the agent's input buffer, so every
conversation ends (FIPA SC00061 §2.4: reply-by). :class:`PendingReplies` keeps those waits,
and the retransmissions of a communicate sent with ``retry_s`` (services/runtime/dedup.py
drops the copies at the receiver).

The protocol state of each conversation is services/runtime/protocol_state.py; the
conversations as an agent's roles take part in them are
:class:`services.runtime.roles.Conversation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

FINAL_REPLIES = frozenset(
    {"inform", "inform-ref", "inform-if", "failure", "refuse", "not-understood", "disconfirm", "confirm"}
)
"""Performatives that answer a request or query for good; ``agree`` only acknowledges."""


@dataclass(init=False)
class Pending:
    """A communicate awaiting a reply: its ``reply_with``, peer, protocol, conversation and
    the POSIX time ``deadline`` (None: no deadline)."""

    reply_with: str
    peer: str
    protocol: str | None
    conversation_id: str | None
    deadline: float | None
    streaming: bool = False  # subscribe/coordinate: many replies, never final by itself
    retry_s: float | None = None
    """Retransmission period (s) until the first reply arrives; ``math.inf``: only when the
    peer reappears; None: sent once."""
    key: str = ""
    payload: bytes = b""
    next_retry: float | None = None
    retransmissions: int = 0

    def __init__(  # written out: the one dataclasses writes is interpreted, this one compiled
        self,
        reply_with: str,
        peer: str,
        protocol: str | None,
        conversation_id: str | None,
        deadline: float | None,
        streaming: bool = False,
        retry_s: float | None = None,
        key: str = "",
        payload: bytes = b"",
        next_retry: float | None = None,
        retransmissions: int = 0,
    ) -> None:
        self.reply_with = reply_with
        self.peer = peer
        self.protocol = protocol
        self.conversation_id = conversation_id
        self.deadline = deadline
        self.streaming = streaming
        self.retry_s = retry_s
        self.key = key
        self.payload = payload
        self.next_retry = next_retry
        self.retransmissions = retransmissions


class PendingReplies:
    """The replies one agent awaits, keyed by the reply-with of what it sent.

    An entry with ``retry_s`` is retransmitted (the same bytes on the same key) every
    ``retry_s`` seconds, and at once when its peer's liveliness token reappears
    (:meth:`retry_now`), until any reply to it arrives or its deadline passes: at-least-once
    delivery over a transport that may lose communicates while a peer or the router restarts.
    The receiver drops the byte-identical copies (services/runtime/dedup.py).
    """

    def __init__(self) -> None:
        self._pending: dict[str, Pending] = {}
        self.earliest = math.inf
        """No entry's deadline or retransmission time (POSIX s) is before it (``math.inf``:
        none is awaited): :meth:`due` and :meth:`expired` have nothing to give before then,
        so an agent's step asks them only from then on. Set by :meth:`expect` and
        :meth:`retry_now`, and to the exact earliest by :meth:`due` and :meth:`expired`."""

    def expect(self, pending: Pending) -> None:
        """Await replies to ``pending.reply_with`` (replacing an entry of that reply-with)."""
        self._pending[pending.reply_with] = pending
        if pending.deadline is not None and pending.deadline < self.earliest:
            self.earliest = pending.deadline
        if pending.next_retry is not None and pending.next_retry < self.earliest:
            self.earliest = pending.next_retry

    def answered(self, in_reply_to: str | None, performative: str) -> Pending | None:
        """Note a reply; returns the pending entry it answers (None if unknown). A final reply
        ends the wait; ``agree`` or a streaming reply keeps it."""
        if in_reply_to is None:
            return None
        entry = self._pending.get(in_reply_to)
        if entry is None:
            return None
        entry.next_retry = None  # the peer has it: no more retransmissions
        if performative in FINAL_REPLIES and not entry.streaming:
            del self._pending[in_reply_to]
        elif entry.streaming:
            entry.deadline = None  # a live stream has answered; its deadline no longer applies
        return entry

    def get(self, reply_with: str) -> Pending | None:
        """The entry awaiting replies to ``reply_with`` (None: not awaited)."""
        return self._pending.get(reply_with)

    def knows(self, in_reply_to: str | None) -> bool:
        """Whether a reply to ``in_reply_to`` is awaited."""
        return in_reply_to is not None and in_reply_to in self._pending

    def forget(self, reply_with: str) -> None:
        """Stop awaiting replies to ``reply_with``."""
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
        self.earliest = self._earliest()
        return out

    def _earliest(self) -> float:
        """The earliest deadline or retransmission time of the entries (``math.inf``: none)."""
        earliest = math.inf
        for p in self._pending.values():
            if p.deadline is not None and p.deadline < earliest:
                earliest = p.deadline
            if p.next_retry is not None and p.next_retry < earliest:
                earliest = p.next_retry
        return earliest

    def next_deadline(self) -> float | None:
        """The earliest reply-by deadline or retransmission time (POSIX s), None if none."""
        times = [p.deadline for p in self._pending.values() if p.deadline is not None]
        times += [
            p.next_retry
            for p in self._pending.values()
            if p.next_retry is not None and p.next_retry != math.inf
        ]
        return min(times) if times else None

    def due(self, now: float) -> list[Pending]:
        """Entries to retransmit now; each is scheduled again ``retry_s`` later."""
        out = []
        for p in self._pending.values():
            if p.next_retry is not None and p.next_retry <= now and p.retry_s is not None:
                p.next_retry = now + p.retry_s
                p.retransmissions += 1
                out.append(p)
        self.earliest = self._earliest()
        return out

    def retry_now(self, peer: str, now: float) -> int:
        """Make every unanswered retransmittable entry to ``peer`` due at once (its liveliness
        token reappeared: a restarted peer has lost what it was sent). Returns how many."""
        n = 0
        for p in self._pending.values():
            if p.peer == peer and p.next_retry is not None:
                p.next_retry = now
                n += 1
        if n:
            self.earliest = min(self.earliest, now)
        return n

    def __len__(self) -> int:
        return len(self._pending)
