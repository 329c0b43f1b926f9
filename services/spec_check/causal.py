"""Causal order of a traffic record: an answer is checked after what it answers.

The traffic recorder (``services.recorder``) numbers communicates in the order they arrive
at it. Zenoh keeps each publisher's order, but not the order between publishers: a query
from a_pl and a_km's answer travel to the recorder over different paths of the router, and
under load the answer can arrive first (seen in CI: ``inform-ref`` recorded 1 place before
the ``query-ref`` it answers). A protocol state machine fed in arrival order would then call
a correct conversation a violation.

:func:`causal_order` moves every communicate whose ``in-reply-to`` names a ``reply-with``
(FIPA SC00061 §2.4) of the same conversation recorded *later* to just after that
communicate; everything else keeps its arrival order. A reply to something never recorded
keeps its place.
"""

from __future__ import annotations

from collections.abc import Sequence

from services.report.load import Message

_Token = tuple[str | None, str]
"""(conversation-id, reply-with) of a communicate."""


def causal_order(messages: Sequence[Message]) -> tuple[list[Message], int]:
    """``messages`` (arrival order) in causal order, and how many were moved later.

    Shapes: a list of the same length with the same elements. O(n) in time and memory."""
    recorded: set[_Token] = set()
    for m in messages:
        if m.comm is not None and m.comm.reply_with is not None:
            recorded.add((m.comm.conversation_id, m.comm.reply_with))
    seen: set[_Token] = set()
    waiting: dict[_Token, list[Message]] = {}
    ordered: list[Message] = []
    moved = 0

    def emit(m: Message) -> None:
        ordered.append(m)
        comm = m.comm
        if comm is None or comm.reply_with is None:
            return
        token = (comm.conversation_id, comm.reply_with)
        seen.add(token)
        for later in waiting.pop(token, []):
            emit(later)

    for m in messages:
        comm = m.comm
        if comm is not None and comm.in_reply_to is not None:
            token = (comm.conversation_id, comm.in_reply_to)
            if token in recorded and token not in seen:
                waiting.setdefault(token, []).append(m)
                moved += 1
                continue
        emit(m)
    # a cycle of answers (malformed traffic) leaves messages waiting: keep them, in arrival order
    rest = sorted((m for ms in waiting.values() for m in ms), key=lambda m: m.rec.seq)
    ordered.extend(rest)
    return ordered, moved
