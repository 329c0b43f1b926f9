"""The critical path of each recorded conversation, counted in crossings of a placement's links:
what a placement adds to a conversation's latency and to the waits its reply-by deadlines bound
(``roco spec what-if``, :mod:`services.spec_check.placement`; docs/spec.md).

A conversation is one conversation-id between two agents (as ``roco spec verify`` follows it);
its *legs* are its communicates, copies left out (:attr:`services.report.load.Message.copy_of`),
in the order they were sent (the publisher's timestamp, else the arrival at the recorder). Its
initiator sent the first, the participant is the other agent, and its *outcome* is the
participant's last communicate in it (what the initiator waits for).

The critical path to the outcome (paper §6: the communication intensity decides the
architecture) is

- the *reply chain*: the outcome, the communicate its in-reply-to names (FIPA SC00061 §2.4),
  the one that one names, and so on back to the opening: each leg crosses the links between its
  sender's and its receiver's hosts once;
- plus the conversations the participant opened while it served this one, as the
  specification's ``waits`` declare them (``serving = "C3:fipa-request", opens =
  ["C4:fipa-query"]``; services/spec/robot_companion.toml), opened between this conversation's
  opening and its outcome: those recorded one after another add up, those that overlapped in
  time (a batch of queries) count once, as the slowest of them; each with its own critical path,
  down to any depth.

A placement's ``crossings(sender, receiver)`` gives the one-way link crossings of one
communicate; a conversation's *half trips* are their sum along its critical path, and the RTT
of the links adds ``half trips × RTT / 2`` to it. A conversation opened by the participant while
it serves several conversations counts in each of them.

A *wait* is a communicate that names a reply-by (FIPA SC00061 §2.4, POSIX s) and the first
answer to it (a communicate of the other agent whose in-reply-to is its reply-with): its budget
is the reply-by less the time it was sent, its recorded wait the time from sending it to the
answer's sending, and its half trips those of the asked and answering legs and of the
conversations the answering agent opened meanwhile (as above). What an agent waits for after an
agree under a deadline it did not send is not in the record.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from services.report.load import Message

Crossings = Callable[[str, str], int]
"""One-way link crossings of a communicate from the first agent to the second (0: same host)."""


@dataclass(frozen=True)
class Leg:
    """One communicate of a conversation: when it was ``t`` sent (POSIX s), by ``sender`` to
    ``receiver``, its ``performative`` and FIPA SC00061 parameters ``reply_with``,
    ``in_reply_to``, ``reply_by`` (POSIX s, None: none)."""

    t: float
    sender: str
    receiver: str
    performative: str
    reply_with: str | None = None
    in_reply_to: str | None = None
    reply_by: float | None = None


@dataclass
class Conversation:
    """A recorded conversation: ``conversation_id``, ``channel``, ``protocol``, its
    ``initiator`` and ``participant``, and its ``legs`` in the order sent (never empty)."""

    conversation_id: str
    channel: str
    protocol: str
    initiator: str
    participant: str
    legs: list[Leg]

    @property
    def kind(self) -> str:
        """``CHANNEL:PROTOCOL``, as the specification's ``waits`` names conversations."""
        return f"{self.channel}:{self.protocol}"

    @property
    def opened(self) -> float:
        return self.legs[0].t

    @property
    def outcome(self) -> Leg | None:
        """The participant's last communicate (None: it sent none)."""
        return next((leg for leg in reversed(self.legs) if leg.sender == self.participant), None)

    @property
    def end(self) -> float:
        """When the outcome was sent, else the last communicate."""
        outcome = self.outcome
        return outcome.t if outcome is not None else self.legs[-1].t


@dataclass(frozen=True)
class Wait:
    """A communicate ``asked`` in ``conversation`` that names a reply-by, and the first
    ``answer`` to it (None: none recorded). ``budget_s``: reply-by less its sending time;
    ``recorded_s``: from its sending to the answer's (None without answer); ``half_trips``:
    link crossings on the way (see the module docstring)."""

    conversation: Conversation
    asked: Leg
    answer: Leg | None
    budget_s: float
    recorded_s: float | None
    half_trips: int

    def predicted_s(self, rtt_s: float) -> float | None:
        """The wait with links of round-trip time ``rtt_s`` (s); None without answer."""
        if self.recorded_s is None:
            return None
        return self.recorded_s + self.half_trips * rtt_s / 2

    def late(self, budget_s: float | None = None) -> bool:
        """The recorded wait exceeds ``budget_s`` (default: its own reply-by) already."""
        budget = self.budget_s if budget_s is None else budget_s
        return self.recorded_s is not None and self.recorded_s > budget

    def breaks_at_s(self, budget_s: float | None = None) -> float | None:
        """The smallest RTT (s) at which a wait in time in the record exceeds ``budget_s``
        (default: its own reply-by); None when no RTT does (no answer, nothing crosses, or
        :meth:`late` already)."""
        budget = self.budget_s if budget_s is None else budget_s
        if self.recorded_s is None or self.half_trips == 0 or self.late(budget):
            return None
        return (budget - self.recorded_s) * 2 / self.half_trips

    def breaks(self, rtt_s: float, budget_s: float | None = None) -> bool:
        """Links of round-trip time ``rtt_s`` make a wait in time in the record exceed
        ``budget_s`` (default: its own reply-by)."""
        at = self.breaks_at_s(budget_s)
        return at is not None and rtt_s > at


def _leg(m: Message) -> Leg | None:
    comm = m.comm
    if comm is None or not m.rec.receivers:
        return None
    return Leg(
        t=m.rec.t_sent if m.rec.t_sent is not None else m.rec.t,
        sender=m.rec.sender,
        receiver=m.rec.receivers[0],
        performative=m.rec.performative,
        reply_with=comm.reply_with,
        in_reply_to=comm.in_reply_to,
        reply_by=comm.reply_by,
    )


def conversations(messages: Iterable[Message]) -> list[Conversation]:
    """The conversations of a record's ``messages`` (copies, communicates without payload,
    conversation-id or protocol left out), in the order they were opened."""
    found: dict[tuple[str, frozenset[str]], tuple[str, str, list[Leg]]] = {}
    for m in messages:
        leg = _leg(m) if m.copy_of is None else None
        cid, protocol = m.rec.conversation_id, m.rec.protocol
        if leg is None or cid is None or protocol is None:
            continue
        key = (cid, frozenset((leg.sender, leg.receiver)))
        found.setdefault(key, (m.rec.channel, protocol, []))[2].append(leg)
    out = []
    for (cid, _), (channel, protocol, legs) in found.items():
        legs.sort(key=lambda leg: leg.t)
        first = legs[0]
        out.append(Conversation(cid, channel, protocol, first.sender, first.receiver, legs))
    return sorted(out, key=lambda c: c.opened)


def waits_of(
    spec_waits: Iterable[tuple[str, Sequence[Mapping[str, object]]]],
) -> dict[str, dict[str, set[str]]]:
    """agent → serving ``CHANNEL:PROTOCOL`` → the kinds it opens then, from each agent's
    ``waits`` in the specification (``(agent, waits)`` pairs; malformed entries are skipped:
    ``roco spec deadlock`` reports them)."""
    out: dict[str, dict[str, set[str]]] = defaultdict(lambda: defaultdict(set))
    for agent, entries in spec_waits:
        for entry in entries:
            serving, opens = entry.get("serving"), entry.get("opens")
            if isinstance(serving, str) and isinstance(opens, list):
                out[agent][serving] |= {x for x in opens if isinstance(x, str)}
    return out


@dataclass
class CriticalPaths:
    """The critical paths of ``convs`` under a placement's ``crossings``, with the agents'
    ``waits`` (:func:`waits_of`)."""

    convs: Sequence[Conversation]
    waits: Mapping[str, Mapping[str, set[str]]]
    crossings: Crossings
    _opened_by: dict[str, list[Conversation]] = field(default_factory=dict, init=False)
    _memo: dict[int, int] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        opened: dict[str, list[Conversation]] = defaultdict(list)
        for c in self.convs:
            opened[c.initiator].append(c)
        self._opened_by = dict(opened)

    def half_trips(self, conv: Conversation) -> int:
        """Link crossings on ``conv``'s critical path to its outcome (module docstring)."""
        key = id(conv)
        if key not in self._memo:
            self._memo[key] = 0  # a conversation nested in itself adds nothing
            outcome = conv.outcome or conv.legs[-1]
            own = self._chain(conv, outcome)
            self._memo[key] = own + self._nested(conv.participant, conv, conv.opened, conv.end)
        return self._memo[key]

    def _chain(self, conv: Conversation, last: Leg) -> int:
        """Crossings of the reply chain from ``last`` back to the opening."""
        by_reply_with = {leg.reply_with: leg for leg in conv.legs if leg.reply_with is not None}
        seen: set[int] = set()
        leg: Leg | None = last
        total = 0
        reached_opening = False
        while leg is not None and id(leg) not in seen:
            seen.add(id(leg))
            total += self.crossings(leg.sender, leg.receiver)
            reached_opening = leg is conv.legs[0]
            leg = by_reply_with.get(leg.in_reply_to) if leg.in_reply_to is not None else None
        if not reached_opening:
            first = conv.legs[0]
            total += self.crossings(first.sender, first.receiver)
        return total

    def _nested(self, agent: str, conv: Conversation, t0: float, t1: float) -> int:
        """Crossings of the conversations ``agent`` opened while serving ``conv`` between ``t0``
        and ``t1``: overlapping ones count as their slowest, the others add up."""
        opens = self.waits.get(agent, {}).get(conv.kind, set())
        if not opens:
            return 0
        inner = [
            c
            for c in self._opened_by.get(agent, [])
            if c is not conv and c.kind in opens and t0 <= c.opened <= t1
        ]
        total, cluster_end, cluster_most = 0, float("-inf"), 0
        for c in inner:  # in the order opened
            if c.opened > cluster_end:
                total += cluster_most
                cluster_most = 0
            cluster_most = max(cluster_most, self.half_trips(c))
            cluster_end = max(cluster_end, c.end)
        return total + cluster_most

    def all_waits(self) -> list[Wait]:
        """:meth:`waits_in` of every conversation, in the order they were opened."""
        return [w for c in self.convs for w in self.waits_in(c)]

    def waits_in(self, conv: Conversation) -> list[Wait]:
        """Every communicate of ``conv`` that names a reply-by, with its first answer."""
        out = []
        for i, asked in enumerate(conv.legs):
            if asked.reply_by is None:
                continue
            answer = next(
                (
                    leg
                    for leg in conv.legs[i + 1 :]
                    if leg.sender == asked.receiver
                    and asked.reply_with is not None
                    and leg.in_reply_to == asked.reply_with
                ),
                None,
            )
            half = self.crossings(asked.sender, asked.receiver)
            if answer is not None:
                half += self.crossings(answer.sender, answer.receiver)
                half += self._nested(answer.sender, conv, asked.t, answer.t)
            out.append(
                Wait(
                    conversation=conv,
                    asked=asked,
                    answer=answer,
                    budget_s=asked.reply_by - asked.t,
                    recorded_s=answer.t - asked.t if answer is not None else None,
                    half_trips=half,
                )
            )
        return out
