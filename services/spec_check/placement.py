"""A placement of the agents on hosts and in processes, and the traffic a recorded run would put
on its links (``roco spec what-if``; paper §5.7 and §6, Figure 13; docs/spec.md).

A placement is written ``--hosts "ag_ex | a_co a_pl a_km a_ta a_hi"`` (hosts split by ``|``,
agents by spaces or commas; every agent of the specification on exactly one host) and
``--merge a_pl+a_km`` (agents in one process: they must share a host). Without ``--hosts`` every
agent is on one host, as ``roco run`` places them. An agent the record never saw (the
specification has grown since the run) may be left out of ``--hosts``: it is placed on the host
of its peers (the agents it has channels with), when they are all on one.

How roco routes (services/hosts/fleet.py, docs/deploy.md): each host runs a Zenoh router its
agents connect to, so two agents of one host talk through that host's router, never through
another's; the routers mesh over TLS, the others with the router of the host that carries the
traffic recorder (the *hub*; a star, as ``roco hosts`` joins the robot's router to the
brain's). The routers pass declarations of interest, so a put crosses to another host only
when something there subscribes to it, and crosses each link once however many subscribe
there. A communicate from A to B is wanted by B and by the recorder, which records every
communicate (``roco/fipa/**``). So it crosses every link on the way from A's host to B's host
and to the recorder's host, each once: a communicate between two agents of a host without the
recorder still crosses once, to the recorder (ag_ex's C5 traffic with a_ta, both on the robot,
crosses to the brain), and two agents on the recorder's host never use a link. Agents merged
into one process hand their communicates over in it: they leave Zenoh, the links and the
record. The record is taken as what the agents send, wherever they ran; the placement only
decides which links it crosses.

What crosses a link is counted as the routers' link carries it: one *put* per Zenoh sample (a
batch of communicates a step sent to one receiver is one put: shared/fipa_codec/batch.py, its
communicates recorded with ``part`` 1, 2, …), its payload plus :data:`PUT_OVERHEAD_B`. Not
counted: the declarations when a process or publisher starts or stops, keep-alives, TCP/IP.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from services.recorder.record import TrafficRecord

PUT_OVERHEAD_B = 98
"""Bytes one put adds to its payload on the routers' link: Zenoh's frame, key expression,
timestamp and source information, and the TLS record around it. Measured with
``scripts/bench_hosts.py --put-overhead`` (as root): 100 puts of 521 B and 100 of 2121 B, 20 a
second, and 40 of 521 B, 2 a second, from a process on the robot's host through roco's transport
(an advanced publisher on a communicate key) to the recorder on the brain, counted by the
relay (services/hosts/relay.py ``--count``): 98 B each in all three, on the 2-core VM of
docs/benchmarks.md."""
MAX_OPTION_CHARS = 2000
"""The longest ``--hosts`` or ``--merge`` text read."""
RECORDER_DEFAULT = "a_hi"
"""The agent whose host carries the recorder unless told (the brain of ``roco hosts``, where the
operator reaches the fleet)."""
NO_RECORDER = "none"

Link = tuple[int, int]
"""Two hosts (their indices, the smaller first) whose routers are joined."""
Edge = tuple[int, int]
"""A link in one direction: (from host, to host)."""


class PlacementError(ValueError):
    """A placement or RTT that cannot be read; the message is one line naming the option."""


@dataclass(frozen=True)
class Placement:
    """Agents on ``hosts`` (each a tuple of agent names, in the order written), ``merged``
    groups (agents in one process), the host index ``recorder`` carries the recorder (None:
    no recorder) and the ``hub`` every other host's router meshes with."""

    hosts: tuple[tuple[str, ...], ...]
    merged: tuple[tuple[str, ...], ...] = ()
    recorder: int | None = 0
    hub: int = 0
    with_peers: tuple[str, ...] = ()
    """Agents ``--hosts`` left out, placed on the host of their peers (:func:`parse_placement`)."""
    _host: dict[str, int] = field(default_factory=dict, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        self._host.update({a: i for i, agents in enumerate(self.hosts) for a in agents})

    def label(self, host: int) -> str:
        """``H1``, ``H2``, … for host index 0, 1, …"""
        return f"H{host + 1}"

    @property
    def recorded_hosts(self) -> tuple[frozenset[str], ...]:
        """Each host's agents but those placed with their peers (not in the record)."""
        return tuple(frozenset(agents) - set(self.with_peers) for agents in self.hosts)

    @property
    def agents(self) -> tuple[str, ...]:
        """Every agent placed, host by host."""
        return tuple(a for agents in self.hosts for a in agents)

    def host_of(self, agent: str) -> int | None:
        """The host index of ``agent`` (None: not placed: outside the platform, or unknown)."""
        return self._host.get(agent)

    def are_merged(self, a: str, b: str) -> bool:
        return any(a in group and b in group for group in self.merged)

    def path(self, start: int, end: int) -> tuple[Edge, ...]:
        """The links (directed) from host ``start`` to host ``end``: none on one host, one to or
        from the hub, else two through it."""
        if start == end:
            return ()
        if self.hub in (start, end):
            return ((start, end),)
        return ((start, self.hub), (self.hub, end))

    def crossings(self, sender: str, receiver: str) -> int:
        """Link crossings of one communicate from ``sender`` to ``receiver`` (0: one host, one
        process, or an agent not placed)."""
        hs, hr = self.host_of(sender), self.host_of(receiver)
        if hs is None or hr is None or self.are_merged(sender, receiver):
            return 0
        return len(self.path(hs, hr))

    def edges_of(self, sender: str, receiver: str) -> frozenset[Edge]:
        """The directed links a put from ``sender`` to ``receiver`` crosses: to the receiver's
        host and to the recorder's, each link once (none for merged agents)."""
        hs, hr = self.host_of(sender), self.host_of(receiver)
        if hs is None or hr is None or self.are_merged(sender, receiver):
            return frozenset()
        wanted = {hr} if self.recorder is None else {hr, self.recorder}
        return frozenset(e for h in wanted for e in self.path(hs, h))

    @property
    def links(self) -> list[Link]:
        """Every link of the placement: each other host with the hub."""
        return [(min(h, self.hub), max(h, self.hub)) for h in range(len(self.hosts)) if h != self.hub]

    def describe(self) -> str:
        """``H1 ag_ex | H2 a_co a_pl …`` with the recorder's host marked and the merges."""
        hosts = " | ".join(
            f"{self.label(i)} {' '.join(agents)}" + (" (+recorder)" if i == self.recorder else "")
            for i, agents in enumerate(self.hosts)
        )
        merged = "; merged: " + ", ".join("+".join(g) for g in self.merged) if self.merged else ""
        return hosts + merged


def _names(text: str) -> list[str]:
    return [n for n in re.split(r"[\s,]+", text.strip()) if n]


def _hosts(
    agents: Sequence[str], text: str | None, unseen: Mapping[str, Collection[str]]
) -> tuple[tuple[tuple[str, ...], ...], tuple[str, ...]]:
    """The hosts ``--hosts`` names, every agent on exactly one, and the agents of ``unseen``
    it left out that :func:`_with_peers` placed. Raises PlacementError."""
    if text is None:
        return (tuple(agents),), ()
    hosts, where = _named(agents, text)
    joined = _with_peers([a for a in agents if a not in where and a in unseen], unseen, where)
    missing = [a for a in agents if a not in where]
    if missing:
        raise PlacementError(f"--hosts: {', '.join(missing)} on no host; place every agent")
    for name in joined:
        hosts[where[name]] += (name,)
    return tuple(hosts), joined


def _named(agents: Sequence[str], text: str) -> tuple[list[tuple[str, ...]], dict[str, int]]:
    """The hosts ``--hosts`` names as written, and each agent's host. Raises PlacementError."""
    if len(text) > MAX_OPTION_CHARS:
        raise PlacementError(f"--hosts: longer than {MAX_OPTION_CHARS} characters")
    hosts = [tuple(_names(part)) for part in text.split("|")]
    where: dict[str, int] = {}
    for i, names in enumerate(hosts):
        if not names:
            raise PlacementError(f"--hosts: host {i + 1} names no agent ({text!r})")
        for name in names:
            _place(agents, name, i, where)
    return hosts, where


def _with_peers(
    left_out: Sequence[str], peers: Mapping[str, Collection[str]], where: dict[str, int]
) -> tuple[str, ...]:
    """Place each agent of ``left_out`` in ``where`` on the one host of its ``peers`` (as many
    rounds as it takes: a peer may be placed so itself); returns those placed, in order. Raises
    PlacementError naming ``--hosts`` for one whose placed peers are on more than one host, or
    none of whose peers is placed."""
    placed: list[str] = []
    todo = list(left_out)
    while todo:
        found = {name: host for name in todo if (host := _peers_host(name, peers[name], where)) is not None}
        if not found:
            them = len(todo) > 1
            raise PlacementError(
                f"--hosts: {', '.join(todo)} on no host; the record never saw {'them' if them else 'it'} "
                f"and no peer is placed: name {'their' if them else 'its'} host in --hosts"
            )
        where.update(found)
        placed += found
        todo = [name for name in todo if name not in found]
    return tuple(placed)


def _peers_host(name: str, peers: Collection[str], where: Mapping[str, int]) -> int | None:
    """The one host of ``name``'s placed ``peers`` (None: none is placed). Raises
    PlacementError naming ``--hosts`` when they are on more than one."""
    on = {where[p] for p in peers if p in where}
    if len(on) > 1:
        at = ", ".join(f"{p} on H{where[p] + 1}" for p in sorted(peers) if p in where)
        raise PlacementError(
            f"--hosts: {name} on no host; the record never saw it and its peers are on more than "
            f"one ({at}): name its host in --hosts"
        )
    return next(iter(on), None)


def _place(agents: Sequence[str], name: str, host: int, where: dict[str, int]) -> None:
    """Note ``name`` on ``host`` in ``where``. Raises PlacementError for an unknown agent or
    one placed already."""
    _known(agents, name, "--hosts")
    if name in where:
        same = f"twice on H{host + 1}" if where[name] == host else f"on H{where[name] + 1} and H{host + 1}"
        raise PlacementError(f"--hosts: {name} is {same}; an agent runs on one host")
    where[name] = host


def _known(agents: Sequence[str], name: str, option: str) -> None:
    if name not in agents:
        raise PlacementError(f"{option}: unknown agent {name!r} (the agents: {', '.join(agents)})")


def _merge_group(agents: Sequence[str], text: str) -> tuple[str, ...]:
    """One ``--merge`` (``a_pl+a_km``): two or more known agents. Raises PlacementError."""
    if len(text) > MAX_OPTION_CHARS:
        raise PlacementError(f"--merge: longer than {MAX_OPTION_CHARS} characters")
    group = tuple(n.strip() for n in text.split("+"))
    if len(group) < 2 or not all(group):
        raise PlacementError(f"--merge {text!r}: name two or more agents joined by + (a_pl+a_km)")
    for name in group:
        _known(agents, name, "--merge")
    return group


def _merges(
    agents: Sequence[str], texts: Sequence[str], host_of: dict[str, int]
) -> tuple[tuple[str, ...], ...]:
    """The groups ``--merge`` names, each on one host, no agent in two. Raises PlacementError."""
    groups = tuple(_merge_group(agents, text) for text in texts)
    named = [n for g in groups for n in g]
    twice = next((n for n in named if named.count(n) > 1), None)
    if twice is not None:
        raise PlacementError(f"--merge: {twice} is in two merges (or named twice)")
    for group in groups:
        _one_host(group, host_of)
    return groups


def _one_host(group: tuple[str, ...], host_of: dict[str, int]) -> None:
    """Raises PlacementError when the merged ``group`` is on more than one host."""
    hosts = sorted({host_of[n] for n in group})
    if len(hosts) > 1:
        on = " and ".join(f"H{h + 1}" for h in hosts)
        raise PlacementError(
            f"--merge {'+'.join(group)}: its agents are on {on}; one process runs on one host"
        )


def parse_placement(
    agents: Sequence[str],
    hosts: str | None = None,
    merges: Sequence[str] = (),
    recorder_with: str = RECORDER_DEFAULT,
    unseen: Mapping[str, Collection[str]] | None = None,
) -> Placement:
    """The placement ``--hosts``, ``--merge`` and ``--recorder-with`` (an agent whose host
    carries the recorder, or ``none``) describe, for the specification's ``agents``. ``unseen``:
    the agents the record never saw, each with its peers (the agents it has channels with); one
    ``--hosts`` leaves out is placed on its peers' host (``Placement.with_peers``). The hub is
    the recorder's host (a_hi's without one). Raises PlacementError naming what is wrong."""
    placed, joined = _hosts(agents, hosts, unseen or {})
    host_of = {a: i for i, names in enumerate(placed) for a in names}
    groups = _merges(agents, merges, host_of)
    if recorder_with != NO_RECORDER:
        if recorder_with not in agents:
            raise PlacementError(f"--recorder-with: unknown agent {recorder_with!r} (an agent, or none)")
        recorder: int | None = host_of[recorder_with]
    else:
        recorder = None
    hub = recorder if recorder is not None else host_of.get(RECORDER_DEFAULT, 0)
    return Placement(placed, groups, recorder, hub, joined)


_RTT = re.compile(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*(us|µs|ms|s)\s*")
_UNIT_S = {"us": 1e-6, "µs": 1e-6, "ms": 1e-3, "s": 1.0}
MAX_RTT_S = 3600.0


def parse_rtt(text: str) -> float:
    """``20ms``, ``0.5s``, ``250 us`` → seconds. Raises PlacementError for anything else, or
    outside 0…:data:`MAX_RTT_S`."""
    found = _RTT.fullmatch(text[:100])
    if found is None or len(text) > 100:
        raise PlacementError(f"--rtt {text!r}: give a time with its unit, e.g. 20ms or 0.5s")
    seconds = float(found.group(1)) * _UNIT_S[found.group(2)]
    if not 0 <= seconds <= MAX_RTT_S:
        raise PlacementError(f"--rtt {text!r}: between 0 and {MAX_RTT_S:g} s")
    return seconds


# ---- the traffic ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Put:
    """One Zenoh sample: its ``records`` (one communicate, or a batch's in order) and its
    payload's size ``size`` on the wire (a batch: the msgpack array of them)."""

    records: tuple[TrafficRecord, ...]

    @property
    def first(self) -> TrafficRecord:
        return self.records[0]

    @property
    def size(self) -> int:
        if len(self.records) == 1:
            return self.first.size
        items = sum(_bin_header(r.size) + r.size for r in self.records)
        return (1 if len(self.records) < 16 else 3) + items


def _bin_header(n: int) -> int:
    """Bytes of a msgpack ``bin`` header for ``n`` bytes (msgpack spec, "bin format family")."""
    return 2 if n < 256 else 3 if n < 65536 else 5


def puts_of(records: Iterable[TrafficRecord]) -> list[Put]:
    """The records grouped into the puts that carried them: a batch's communicates share their
    publisher's ``source`` and sequence number ``sn``; a record without them is a put alone."""
    grouped: dict[tuple[str, int] | int, list[TrafficRecord]] = {}
    for r in records:
        key: tuple[str, int] | int = (
            (r.source, r.sn) if r.source is not None and r.sn is not None else -1 - r.seq
        )
        grouped.setdefault(key, []).append(r)
    return [Put(tuple(sorted(rs, key=lambda r: r.part))) for rs in grouped.values()]


@dataclass
class Flow:
    """What one channel (or everything) carries one way: ``communicates``, their ``payload_b``
    bytes, ``puts`` and ``wire_b`` (puts' payloads plus :data:`PUT_OVERHEAD_B` each), and both
    per second of the clock (POSIX s, floored)."""

    communicates: int = 0
    payload_b: int = 0
    puts: int = 0
    wire_b: int = 0
    payload_per_s: Counter[int] = field(default_factory=Counter)
    wire_per_s: Counter[int] = field(default_factory=Counter)

    def add_put(self, put: Put, records: Sequence[TrafficRecord] | None = None) -> None:
        """Count ``put`` (its wire bytes) and ``records`` of it (default: all)."""
        second = math.floor(put.first.t)
        wire = put.size + PUT_OVERHEAD_B
        self.puts += 1
        self.wire_b += wire
        self.wire_per_s[second] += wire
        for r in put.records if records is None else records:
            self.communicates += 1
            self.payload_b += r.size
            self.payload_per_s[second] += r.size


def kbps(n_bytes: float, seconds: float) -> float:
    """``n_bytes`` over ``seconds`` in kbit/s (1 kbit = 1000 bit)."""
    return n_bytes * 8 / 1000 / seconds if seconds > 0 else 0.0


def peak_kbps(per_s: Counter[int]) -> float:
    """The busiest second of ``per_s`` (bytes per second of the clock) in kbit/s."""
    return kbps(max(per_s.values(), default=0), 1.0)


@dataclass
class Traffic:
    """A record's traffic under a placement: per directed link and channel (``links``: edge →
    channel → :class:`Flow`) and everything per edge (``totals``); ``gone``: per channel, what
    merged agents hand over in process; ``crossing``: the records that cross some link;
    ``unplaced``: records of agents the placement does not place."""

    links: dict[Edge, dict[str, Flow]] = field(default_factory=dict)
    totals: dict[Edge, Flow] = field(default_factory=dict)
    gone: dict[str, Flow] = field(default_factory=dict)
    crossing: list[TrafficRecord] = field(default_factory=list)
    unplaced: int = 0


def traffic(records: Sequence[TrafficRecord], placement: Placement) -> Traffic:
    """What ``records`` put on each link of ``placement`` (module docstring)."""
    out = Traffic()
    for put in puts_of(records):
        r = put.first
        receiver = r.receivers[0] if r.receivers else "?"
        if placement.host_of(r.sender) is None or placement.host_of(receiver) is None:
            out.unplaced += len(put.records)
            continue
        if placement.are_merged(r.sender, receiver):
            out.gone.setdefault(r.channel, Flow()).add_put(put)
            continue
        edges = placement.edges_of(r.sender, receiver)
        if edges:
            out.crossing.extend(put.records)
        for edge in edges:
            out.links.setdefault(edge, {}).setdefault(r.channel, Flow()).add_put(put)
            out.totals.setdefault(edge, Flow()).add_put(put)
    return out
