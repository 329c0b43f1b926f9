"""The run folder's record of which processes were up: ``presence.jsonl``, written by the traffic
recorder from the processes' liveliness tokens (services/runtime/keys.py ``alive_key``).

An agent acts on its peers' tokens as well as on communicates (a standing subscription opens when
the peer's token appears: services/runtime/roles/subscriptions.py), so a replay that is to reproduce it
(services/replay) feeds both. A token carries no publisher's timestamp (a Zenoh liveliness sample
has none, timestamping on or off), so an event's time is the recorder's, and a token reaches the
recorder over a path of its own (through the router, while the agents are linked directly): it
may be recorded after communicates that its appearance caused. The replay puts each event in its
place by cause (services/replay/presence.py). Each recorder incarnation writes
first a *snapshot*, the tokens alive when it began to watch (one line per token, ``snapshot``
true; a token alive before the run's first recorder began was alive from the replay's start), then
one line per token that appeared or disappeared. A token that changed while no recorder ran is
missing from the file: the next incarnation's snapshot says how things stood then. This module is
only the format, so that the recorder and the replay read it without importing each other.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import BinaryIO

import msgspec

PRESENCE_JSONL = "presence.jsonl"
"""The run folder's presence record: one JSON :class:`PresenceEvent` per line, in the order the
recorder saw them."""

MAX_LINE_BYTES = 4096
"""A longer line is no presence event (the file is read whole; names are short)."""


class PresenceEvent(msgspec.Struct, frozen=True, kw_only=True):
    """One process's liveliness token seen by the recorder: ``name`` the process (an agent's name,
    ``recorder``, ``world``…), ``alive`` whether its token appeared (True) or disappeared, ``t``
    when the recorder saw it (POSIX s, the recorder's clock: the token carries none of its
    owner's; module docstring), ``seq`` how many communicates the traffic record held then
    (the next ``traffic.jsonl`` ``seq``), ``incarnation`` the recorder incarnation that saw it
    (as in ``traffic.jsonl``), ``snapshot`` True for a token alive when that incarnation began to
    watch (``t`` is then that moment)."""

    name: str
    alive: bool
    t: float
    seq: int
    incarnation: str
    snapshot: bool = False


_encode = msgspec.json.Encoder().encode
_decode = msgspec.json.Decoder(PresenceEvent).decode


class PresenceWriter:
    """Appends :class:`PresenceEvent`\\ s to ``run_dir/presence.jsonl``, opened at the first one.
    Raises OSError when the file cannot be written."""

    def __init__(self, run_dir: Path) -> None:
        self._path = run_dir / PRESENCE_JSONL
        self._f: BinaryIO | None = None

    def write(self, events: list[PresenceEvent]) -> None:
        """Append ``events`` (one line each) and flush. Raises OSError."""
        if not events:
            return
        if self._f is None:
            self._f = self._path.open("ab")
        self._f.write(b"".join(_encode(e) + b"\n" for e in events))
        self._f.flush()

    def close(self) -> None:
        """Close the file, if it was opened."""
        if self._f is not None:
            self._f.close()


def read_presence(run_dir: Path) -> list[PresenceEvent] | None:
    """The presence events of ``run_dir`` in file order; None when the run has no presence record
    (recorded before the recorder wrote one). A line that is not an event (a killed recorder's
    torn last line) is skipped. Raises OSError when the file exists but cannot be read."""
    path = run_dir / PRESENCE_JSONL
    if not path.exists():
        return None
    events = []
    for line in path.read_bytes().splitlines():
        if not line.strip() or len(line) > MAX_LINE_BYTES:
            continue
        try:
            events.append(_decode(line))
        except (msgspec.DecodeError, msgspec.ValidationError):
            continue
    return events


def absences(events: list[PresenceEvent]) -> dict[str, list[tuple[float, float]]]:
    """When each process's token was gone, from the presence ``events`` (in file order): for every
    name the record shows alive at least once, its absences as ``(from, to)`` POSIX s, in time
    order (``-inf``: absent before the record saw it first; ``inf``: still gone at its end).

    Where no recorder watched (between one incarnation's last event and the next one's snapshot),
    a token that disappeared is taken as gone from the earliest moment it may have gone, and one
    that came back as back at the latest: the absences are as wide as the record allows. A token
    in the first incarnation's snapshot was there from the start."""
    watch = _Absences(events[0].incarnation if events else "")
    for e in events:
        watch.read(e)
    return watch.finish()


class _Absences:
    """The reading of :func:`absences`: who is alive, since when each absent one is away, and
    the snapshot of the recorder incarnation being read (None: its snapshot is over)."""

    def __init__(self, first: str) -> None:
        self.first = first
        self.away: dict[str, list[tuple[float, float]]] = {}
        self.gone_since: dict[str, float] = {}
        self.alive: set[str] = set()
        self.incarnation: str | None = None
        self.snapshot: set[str] | None = None
        self.last_t = -math.inf  # the latest event read
        self.gap_start = -math.inf  # the previous incarnation's latest event

    def read(self, e: PresenceEvent) -> None:
        if e.snapshot and e.incarnation != self.incarnation:  # an incarnation begins to watch
            self._end_snapshot()
            self.incarnation, self.snapshot, self.gap_start = e.incarnation, set(), self.last_t
        elif not e.snapshot:
            self._end_snapshot()
        if e.snapshot and self.snapshot is not None:
            self.snapshot.add(e.name)
        if e.alive:  # in the first incarnation's snapshot: alive before the record began
            self._back(e.name, e.t, e.snapshot and e.incarnation == self.first)
        elif e.name in self.alive:
            self.alive.discard(e.name)
            self.gone_since[e.name] = e.t
        self.last_t = max(self.last_t, e.t)

    def _back(self, name: str, t: float, from_start: bool) -> None:
        since = self.gone_since.pop(name, -math.inf)
        if name not in self.alive and not (from_start and since == -math.inf):
            self.away.setdefault(name, []).append((since, t))
        self.alive.add(name)

    def _end_snapshot(self) -> None:
        """A snapshot read in full: who was alive before and is not in it went while no
        recorder watched, as early as the previous incarnation's last event."""
        if self.snapshot is None:
            return
        for name in sorted(self.alive - self.snapshot):
            self.alive.discard(name)
            self.gone_since[name] = self.gap_start
        self.snapshot = None

    def finish(self) -> dict[str, list[tuple[float, float]]]:
        self._end_snapshot()
        for name, since in self.gone_since.items():
            self.away.setdefault(name, []).append((since, math.inf))
        return {name: sorted(spans) for name, spans in self.away.items()}


def away_between(spans: list[tuple[float, float]], t0: float, t1: float) -> tuple[float, float] | None:
    """The first absence of ``spans`` (:func:`absences`) that overlaps ``[t0, t1]`` (POSIX s),
    None when the process was present throughout."""
    for start, end in spans:
        if start <= t1 and end >= t0:
            return start, end
    return None
