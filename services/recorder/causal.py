"""Causal order of a traffic record: an answer after what it answers.

The traffic recorder (``services.recorder``) numbers communicates in the order they arrive
at it. Zenoh keeps each publisher's order, but not the order between publishers: a query
from a_pl and a_km's answer travel to the recorder over different paths (through the router,
or each agent's own link to the recorder when agents are linked directly), and the answer can
arrive first (seen in CI: ``inform-ref`` recorded 1 place before the ``query-ref`` it
answers). A protocol state machine fed in arrival order would then call a correct
conversation a violation (services/spec_check, services/report), and a replayed agent would
get an answer before its question (services/replay). Both orderings here work on any
recorded communicate that carries its record and decoded communicate (:class:`Recorded`).

:func:`causal_order` moves every communicate whose ``in-reply-to`` names a ``reply-with``
(FIPA SC00061 §2.4) of the same conversation recorded *later* to just after that
communicate; everything else keeps its arrival order. A reply to something never recorded
keeps its place.

:func:`send_order` then mends the other crossing of two publishers' paths: a_ta's next L_SW
inform, sent once a_co's confirm of the previous one had arrived, recorded a few microseconds
before that confirm (seen in a test run: the informs 10 µs before the confirm). Nothing in the
inform names the confirm, so the send times (``t_sent``, each publisher's clock) are the
evidence: a communicate recorded after one of the other party's in the same conversation, but
sent before it, and not answering it, is checked first. The verdict is then that of a causal
order the record allows; on two hosts that trusts their clocks within the few recorded
communicates of the conversation the move looks across (``SEND_ORDER_WINDOW``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Generic, Protocol, TypeVar

from services.recorder.record import TrafficRecord
from shared.fipa_codec import Communicate


class Recorded(Protocol):
    """A communicate of a traffic record as the orderings read it: its record ``rec`` and the
    decoded communicate ``comm`` (None when its payload does not decode); services/report/load.py
    ``Message`` is one."""

    @property
    def rec(self) -> TrafficRecord: ...

    @property
    def comm(self) -> Communicate | None: ...


Message = TypeVar("Message", bound=Recorded)
"""The kind of recorded communicate ordered: an ordering returns the elements it was given."""

Token = tuple[str | None, str]
"""(conversation-id, reply-with) of a communicate."""


def offered(m: Message) -> Token | None:
    """The token an answer to ``m`` names (its reply-with), None when it has none."""
    comm = m.comm
    if comm is None or comm.reply_with is None:
        return None
    return comm.conversation_id, comm.reply_with


def answered(m: Message) -> Token | None:
    """The token ``m`` answers (its in-reply-to), None when it answers nothing."""
    comm = m.comm
    if comm is None or comm.in_reply_to is None:
        return None
    return comm.conversation_id, comm.in_reply_to


@dataclass
class _CausalReplay(Generic[Message]):
    """The record replayed in arrival order (:meth:`take`): an answer to a communicate recorded
    later waits for it; a communicate taken brings in the answers waiting for it
    (:meth:`emit`)."""

    recorded: set[Token]
    """The tokens some communicate of the record offers."""
    seen: set[Token] = field(default_factory=set)
    waiting: dict[Token, list[Message]] = field(default_factory=dict)
    ordered: list[Message] = field(default_factory=list)
    moved: int = 0

    def take(self, m: Message) -> None:
        token = answered(m)
        if token is not None and token in self.recorded and token not in self.seen:
            self.waiting.setdefault(token, []).append(m)
            self.moved += 1
            return
        self.emit(m)

    def emit(self, m: Message) -> None:
        self.ordered.append(m)
        token = offered(m)
        if token is None:
            return
        self.seen.add(token)
        for later in self.waiting.pop(token, []):
            self.emit(later)


def causal_order(messages: Sequence[Message]) -> tuple[list[Message], int]:
    """``messages`` (arrival order) in causal order, and how many were moved later.

    Shapes: a list of the same length with the same elements. O(n) in time and memory."""
    replay: _CausalReplay[Message] = _CausalReplay({t for m in messages if (t := offered(m)) is not None})
    for m in messages:
        replay.take(m)
    # a cycle of answers (malformed traffic) leaves messages waiting: keep them, in arrival order
    rest = sorted((m for ms in replay.waiting.values() for m in ms), key=lambda m: m.rec.seq)
    replay.ordered.extend(rest)
    return replay.ordered, replay.moved


SEND_ORDER_WINDOW = 16
"""How many communicates of the same conversation after one :func:`send_order` looks through
for one sent before it."""
SEND_ORDER_REACH = 8 * SEND_ORDER_WINDOW
"""How many communicates of any conversation after one :func:`send_order` looks through at most
(other conversations' traffic lies between a burst of one party's communicates and the other's
answers: seen in a test run, confirms recorded 38 places after the inform sent after them)."""

_Pair = tuple[str | None, frozenset[str]]
"""(conversation-id, the two agents) of a communicate: its conversation."""


def _pair(m: Message) -> _Pair:
    return (m.rec.conversation_id, frozenset((m.rec.sender, *m.rec.receivers[:1])))


def _sent_earlier(a: TrafficRecord, b: TrafficRecord) -> bool:
    """True when ``b`` was sent before ``a``, in a conversation (both send times known)."""
    return (
        a.conversation_id is not None
        and a.t_sent is not None
        and b.t_sent is not None
        and b.t_sent < a.t_sent
    )


def _sent_first(m: Message, n: Message) -> bool:
    """True when ``n`` (recorded after ``m``) belongs before it: the same conversation, sent by
    ``m``'s receiver to ``m``'s sender before ``m`` was sent, and not an answer to ``m``."""
    a, b = m.rec, n.rec
    if not _sent_earlier(a, b):
        return False
    if b.sender == a.sender or a.sender not in b.receivers[:1] or _pair(m) != _pair(n):
        return False
    answers = n.comm.in_reply_to if n.comm is not None else None
    return answers is None or m.comm is None or answers != m.comm.reply_with


def send_order(messages: Sequence[Message]) -> tuple[list[Message], int]:
    """``messages`` (causal order by answers, :func:`causal_order`) with each communicate that
    was sent before one of the other party's, and recorded after it within the next
    ``SEND_ORDER_WINDOW`` communicates of their conversation (and ``SEND_ORDER_REACH`` of any),
    moved before that one (module docstring), and how many were moved.

    Shapes: a list of the same length with the same elements. A move brings to a place a
    communicate of the reach after it sent before the one there, so each place takes at most
    ``SEND_ORDER_REACH`` moves, whatever the record's send times: O(n · SEND_ORDER_REACH²) at
    worst, O(n · SEND_ORDER_REACH) for a record with few crossings."""
    ordered = list(messages)
    moved = 0
    i = 0
    while i < len(ordered):
        j = _first_sent_before(ordered, i)
        if j is None:
            i += 1
            continue
        ordered.insert(i, ordered.pop(j))
        moved += 1
    return ordered, moved


def _first_sent_before(ordered: list[Message], i: int) -> int | None:
    """The place of the first communicate after ``ordered[i]`` that belongs before it
    (:func:`_sent_first`), looked for within the window and reach of :func:`send_order`."""
    m = ordered[i]
    pair = _pair(m)
    same = 0
    for j in range(i + 1, min(i + 1 + SEND_ORDER_REACH, len(ordered))):
        if _pair(ordered[j]) != pair:
            continue
        if _sent_first(m, ordered[j]):
            return j
        same += 1
        if same >= SEND_ORDER_WINDOW:
            return None
    return None
