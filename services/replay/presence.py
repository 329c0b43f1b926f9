"""Which peers a replayed agent sees alive, and when that changes: the run folder's presence
record (services/recorder/presence.py) turned into the tokens the replay's bus holds.

An agent acts on its peers' liveliness tokens (a standing subscription opens when its peer's
token appears, a conversation with a peer that went away is given up), so the replay puts each
token on its bus and takes it off when the agent saw that happen. The tokens alive when the
run's first recorder incarnation began to watch were alive from the start; each later
incarnation's snapshot says how things stood after a time no recorder watched (a token alive then
and not in it went away, one in it and not alive appeared). A run recorded without a presence
record has every agent of the specification alive from the start.

When the agent saw a change is not when the recorder did. A token carries no publisher's
timestamp (a Zenoh liveliness sample has none, timestamping on or off), and it reaches the
recorder over a path of its own (through the router; the agents are linked directly): the
recorder may see a token after the communicates the agent sent because it appeared (seen: ag_ex's
token 3.4 ms after a_ta's subscription to its power-ons). So a change is taken when the paths
say the agent saw it (:func:`timeline`, ``paths``), and a token's appearance no later than the
first communicate the agent sent its owner, by the agent's own timestamps, that it may have
caused: one sent in the time the recorder may lag behind (``window``) before the recorder saw the
token, with no input reaching the agent in that time before it (an input would explain it).
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections.abc import Callable
from dataclasses import dataclass, field

from services.recorder.presence import PresenceEvent
from services.replay.record import RECORDER, Paths


@dataclass(frozen=True)
class Change:
    """``name``'s token appeared (``alive``) or disappeared at POSIX time ``t``."""

    t: float
    name: str
    alive: bool


@dataclass
class Timeline:
    """``initial``: the names alive when the replayed agent starts; ``changes``: what changed
    after, in time order; ``recorded``: False when the run holds no presence record (then
    ``initial`` is every agent of the specification)."""

    initial: set[str]
    changes: list[Change] = field(default_factory=list)
    recorded: bool = True


def timeline(
    events: list[PresenceEvent] | None,
    agent: str,
    start: float,
    agents: list[str],
    lag: float = 0.0,
    *,
    paths: Paths | None = None,
    sent: dict[str, list[float]] | None = None,
    came: list[float] | None = None,
    window: float = 0.0,
) -> Timeline:
    """The tokens the replay of ``agent`` (which starts at POSIX time ``start``) sees, from the
    presence ``events`` in file order (None: no presence record; then ``agents`` are alive from
    the start). The replayed agent's own token is never in it.

    A change of a token is taken as the agent saw it: with ``paths`` (where the processes ran:
    services/replay/record.py), the recorder's time less the path from the token's owner to the
    recorder, more the path from the owner to the agent (on one host, the recorder's time; across
    a link, the recorder sees a token of the agent's side later than the agent, one of its own
    side earlier); without, the recorder's time less ``lag`` (s: how much later the recorder sees
    what happens at the agent, its communicates' least delay, :func:`lag_of`). An appearance is
    then taken no later than the first time in ``sent`` (per receiver: when the agent sent each
    of its communicates to it, ascending) up to ``window`` (s) before it with no time in ``came``
    (when each input reached the agent, ascending) in the ``window`` before that (module
    docstring), and never before the token's change before it."""
    if events is None:
        return Timeline({a for a in agents if a != agent}, recorded=False)
    first = events[0].incarnation if events else ""
    recorded = _changes([e for e in events if e.name != agent], first)
    return _split(_placed(recorded, _seen_at(agent, paths, lag), sent or {}, came or [], window), start)


def _placed(
    recorded: list[Change],
    seen_at: Callable[[Change], float],
    sent: dict[str, list[float]],
    came: list[float],
    window: float,
) -> list[Change]:
    """The ``recorded`` changes at the times the agent saw them (:func:`timeline`)."""
    changes: list[Change] = []
    last: dict[str, float] = {}
    for c in recorded:
        t = seen_at(c)
        if c.alive:
            t = max(_caused(t, sent.get(c.name, []), came, window), last.get(c.name, -math.inf))
        last[c.name] = t
        changes.append(Change(t, c.name, c.alive))
    return changes


def _seen_at(agent: str, paths: Paths | None, lag: float) -> Callable[[Change], float]:
    """When ``agent`` saw a change the recorder saw (:func:`timeline`)."""
    if paths is None:
        return lambda c: c.t - lag
    return lambda c: c.t - paths.between(c.name, RECORDER) + paths.between(c.name, agent)


def _split(changes: list[Change], start: float) -> Timeline:
    """The tokens alive at ``start`` (POSIX s) after ``changes``, and the changes after it, in
    time order."""
    initial: set[str] = set()
    later = []
    for c in sorted(changes, key=lambda c: c.t):
        if c.t <= start:
            (initial.add if c.alive else initial.discard)(c.name)
        else:
            later.append(c)
    return Timeline(initial, later)


def _caused(t: float, sent: list[float], came: list[float], window: float) -> float:
    """When a token that the agent is taken to have seen appear at ``t`` appeared at the
    latest: the first of ``sent`` (ascending) in the ``window`` before ``t`` that no input
    explains (none of ``came``, ascending, in the ``window`` before it), else ``t``."""
    for s in sent[bisect_left(sent, t - window) :]:
        if s >= t:
            break
        i = bisect_left(came, s - window)
        if i == len(came) or came[i] > s:
            return s
    return t


def _changes(events: list[PresenceEvent], first: str) -> list[Change]:
    """Each change of a token ``events`` show, in their order; the snapshot of the incarnation
    ``first`` at the start of time, a later one's at its time (module docstring)."""
    snapshots: dict[str, set[str]] = {}
    for e in events:
        if e.snapshot:
            snapshots.setdefault(e.incarnation, set()).add(e.name)
    alive: set[str] = set()
    changes: list[Change] = []
    for e in events:
        if e.snapshot and e.incarnation in snapshots:  # reconciled once, at its first line
            t = float("-inf") if e.incarnation == first else e.t
            changes += _reconcile(alive, snapshots.pop(e.incarnation), t)
        elif not e.snapshot and (e.name in alive) != e.alive:
            changes.append(Change(e.t, e.name, e.alive))
            (alive.add if e.alive else alive.discard)(e.name)
    return changes


def _reconcile(alive: set[str], seen: set[str], t: float) -> list[Change]:
    """What a snapshot ``seen`` at ``t`` changes of ``alive`` (made equal to it)."""
    changes = [Change(t, n, False) for n in sorted(alive - seen)]
    changes += [Change(t, n, True) for n in sorted(seen - alive)]
    alive.clear()
    alive.update(seen)
    return changes


def lag_of(delays: list[float]) -> float:
    """The least of ``delays`` (s: a communicate's arrival at the recorder less its send time,
    each of the replayed agent's that carried one) above 0; 0 when there is none."""
    return min((d for d in delays if d > 0), default=0.0)
