"""Which peers a replayed agent sees alive, and when that changes: the run folder's presence
record (services/recorder/presence.py) turned into the tokens the replay's bus holds.

An agent acts on its peers' liveliness tokens (a standing subscription opens when its peer's
token appears, a conversation with a peer that went away is given up), so the replay puts each
token on its bus and takes it off when the recorder saw that happen. The tokens alive when the
run's first recorder incarnation began to watch were alive from the start; each later
incarnation's snapshot says how things stood after a time no recorder watched (a token alive then
and not in it went away, one in it and not alive appeared). A run recorded without a presence
record has every agent of the specification alive from the start.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from services.recorder.presence import PresenceEvent


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
    events: list[PresenceEvent] | None, agent: str, start: float, agents: list[str], lag: float = 0.0
) -> Timeline:
    """The tokens the replay of ``agent`` (which starts at POSIX time ``start``) sees, from the
    presence ``events`` in file order (None: no presence record; then ``agents`` are alive from
    the start). The replayed agent's own token is never in it. ``lag`` (s): how much later the
    recorder sees what happens at the agent (its communicates' least delay, :func:`lag_of`); each
    change is taken that much earlier, as the agent saw it (on one host, or the recorder's, both
    see a token at about the same time; across a link, the recorder later)."""
    if events is None:
        return Timeline({a for a in agents if a != agent}, recorded=False)
    first = events[0].incarnation if events else ""
    initial: set[str] = set()
    later = []
    for c in _changes([e for e in events if e.name != agent], first):
        c = Change(c.t - lag, c.name, c.alive)
        if c.t <= start:
            (initial.add if c.alive else initial.discard)(c.name)
        else:
            later.append(c)
    return Timeline(initial, later)


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
