"""``roco spec what-if RUN``: a placement weighed before it is built, from a run's record (paper
§5.7 and §6: "the bandwidth of communication channels and communication intensity can be
estimated in the development; on their basis, it is possible to properly define or redefine the
architecture"; Figure 13; docs/spec.md). :func:`what_if` gathers it as data;
:mod:`services.spec_check.whatif_text` writes it.

For a placement (:mod:`services.spec_check.placement`: hosts, merges, where the recorder is) it
tells, from ``traffic.jsonl`` and ``traffic.msgpack``:

- per link and direction, per channel: communicates, bytes, mean and peak kbit/s (1 s windows
  of the clock), and the link's total on the wire (puts plus their overhead);
- the sizes of the communicates that cross against the specification's estimates (``sizes`` per
  channel, protocol and performative), and the link's mean if every one were at its estimate's
  upper bound;
- per conversation kind, the round trips its critical path crosses and what a link's RTT adds
  (:mod:`services.spec_check.critical_path`);
- the reply-by deadlines: those the agents sent (each communicate's reply-by) and those the
  roles declare (``reply_by_s``), which the RTT would break, and the smallest RTT that breaks each;
- what merged agents take off Zenoh, and the hand-overs their critical paths no longer wait for;
- for a run of ``roco hosts`` whose placement is the one asked, what the link carried, as the
  relay counted it (``link_bytes.jsonl``), beside the prediction.
"""

from __future__ import annotations

import json
import math
import statistics
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from services.recorder.record import HOSTS_JSON, TrafficRecord, read_link_bytes
from services.report.load import RunData, load_run
from services.spec.model import SpecError, SystemSpec
from services.spec_check.critical_path import Conversation, CriticalPaths, Wait, conversations, waits_of
from services.spec_check.placement import Edge, Placement, PlacementError, Traffic, traffic

MAX_HOSTS_JSON = 1 << 20


@dataclass(frozen=True)
class RoleReplyBy:
    """An initiator role's declared reply-by: ``agent`` opens ``protocol`` on ``channel`` and
    waits ``reply_by_s`` (s) for the answer (services/runtime/roles/ ``reply_by_s``)."""

    agent: str
    channel: str
    protocol: str
    reply_by_s: float


@dataclass(frozen=True)
class SizeRow:
    """The communicates of one channel, protocol and performative that cross: ``sizes`` in
    bytes, the specification's ``estimate`` [min, max] (None: none given) and how many fall
    ``outside`` it."""

    channel: str
    protocol: str
    performative: str
    sizes: tuple[int, ...]
    estimate: tuple[int, int] | None

    @property
    def outside(self) -> int:
        if self.estimate is None:
            return 0
        low, high = self.estimate
        return sum(1 for s in self.sizes if not low <= s <= high)


@dataclass(frozen=True)
class Measured:
    """What a two-host run's link carried in the record's window (the relay's count): bytes
    per directed link ``by_edge`` and per second of both ways ``per_s``."""

    by_edge: dict[Edge, int]
    per_s: dict[int, int]


@dataclass
class WhatIf:
    """Everything ``roco spec what-if`` says of one run folder and placement (module
    docstring); ``first_t``/``last_t``: the record's first and last communicate (POSIX s)."""

    run_dir: Path
    placement: Placement
    rtt_s: float | None
    first_t: float
    last_t: float
    traffic: Traffic
    convs: list[Conversation]
    paths: CriticalPaths
    merged_paths: CriticalPaths | None
    roles: list[RoleReplyBy]
    spec: SystemSpec
    one_way_s: float | None = None
    """Median recorded one-way time (recorder arrival less publisher timestamp) of the
    communicates between merged agents (None: no merge, or no timestamps)."""
    measured: Measured | None = None
    notes: list[str] = field(default_factory=list)
    communicates: int = 0
    waits: list[Wait] = field(default_factory=list)
    """Every communicate that named a reply-by, with its answer (critical_path.py)."""

    @property
    def window_s(self) -> int:
        """The whole seconds of the clock the record spans (means are over these)."""
        return math.floor(self.last_t) - math.floor(self.first_t) + 1

    def declared(self, wait: Wait) -> float | None:
        """The reply-by (s) the role that opened ``wait``'s conversation declares, when ``wait``
        is that conversation's opening; else None."""
        c = wait.conversation
        if wait.asked is not c.legs[0]:
            return None
        return next(
            (
                r.reply_by_s
                for r in self.roles
                if (r.agent, r.channel, r.protocol) == (c.initiator, c.channel, c.protocol)
            ),
            None,
        )

    def broken(self) -> list[Wait]:
        """The waits in time in the record that the RTT makes exceed their reply-by or their
        role's declared one (none without an RTT)."""
        rtt = self.rtt_s
        if rtt is None:
            return []
        return [x for x in self.waits if x.breaks(rtt) or self._breaks_declared(x, rtt)]

    def _breaks_declared(self, wait: Wait, rtt_s: float) -> bool:
        declared = self.declared(wait)
        return declared is not None and wait.breaks(rtt_s, declared)


# ---- the declared reply-by of the roles ------------------------------------------------------


def declared_reply_by(spec: SystemSpec) -> tuple[list[RoleReplyBy], list[str]]:
    """The initiator roles that declare a reply-by, from each agent's ``ROLES`` (its class
    imported as the launcher does, services/runtime/main.py ``agent_class``), and notes on
    agents whose class cannot be loaded."""
    from services.runtime.main import agent_class
    from services.runtime.roles import INITIATOR, expand_roles

    out, notes = [], []
    for a in spec.agents:
        try:
            declared = agent_class(spec, a.name).ROLES or ()
        except SpecError as exc:
            notes.append(f"{exc}: its roles' reply-by not weighed")
            continue
        out += [
            RoleReplyBy(a.name, d.channel, d.protocol, d.reply_by_s)
            for d in expand_roles(spec, a.name, declared)
            if d.role == INITIATOR and d.reply_by_s is not None
        ]
    return out, notes


# ---- building it -----------------------------------------------------------------------------


def _run_hosts(run_dir: Path) -> tuple[set[str], set[str]] | None:
    """The processes on the robot and on the brain of a two-host run (``hosts.json``), None
    when the run has no readable one."""
    path = run_dir / HOSTS_JSON
    try:
        if path.stat().st_size > MAX_HOSTS_JSON:
            return None
        hosts = json.loads(path.read_text())["hosts"]
        return set(hosts["robot"]["processes"]), set(hosts["brain"]["processes"])
    except (OSError, ValueError, LookupError, TypeError):
        return None


def _as_run(run_dir: Path, placement: Placement) -> tuple[int, int] | None:
    """(robot, brain): ``placement``'s host indices of a two-host run's robot and brain when it
    places the agents as the run did (two hosts, the recorder on the brain, no merge; an agent
    placed with its peers is not in the record, so it changes nothing); None otherwise."""
    hosts = _run_hosts(run_dir)
    if hosts is None or len(placement.hosts) != 2 or placement.merged:
        return None
    index = {agents: i for i, agents in enumerate(placement.recorded_hosts)}
    robot, brain = (index.get(frozenset(h & set(placement.agents))) for h in hosts)
    if robot is None or brain is None or placement.recorder != brain:
        return None
    return robot, brain


def _measured(run_dir: Path, placement: Placement, first_t: float, last_t: float) -> Measured | None:
    """The relay's count over the record's seconds, for a two-host run placed as
    ``placement`` (:func:`_as_run`); None otherwise."""
    hosts = _as_run(run_dir, placement)
    if hosts is None:
        return None
    robot, brain = hosts
    seconds = [s for s in read_link_bytes(run_dir) if math.floor(first_t) <= s.t <= math.floor(last_t)]
    if not seconds:
        return None
    return Measured(
        {(robot, brain): sum(s.up for s in seconds), (brain, robot): sum(s.down for s in seconds)},
        {int(s.t): s.up + s.down for s in seconds},
    )


def _one_way_s(records: Sequence[TrafficRecord], placement: Placement) -> float | None:
    """The median of arrival at the recorder less the publisher's time of the communicates
    between merged agents (None: none with a timestamp)."""
    between = [
        r.t - r.t_sent
        for r in records
        if r.t_sent is not None and r.receivers and placement.are_merged(r.sender, r.receivers[0])
    ]
    return statistics.median(between) if between else None


def _paths(
    convs: list[Conversation], spec: SystemSpec, placement: Placement
) -> tuple[CriticalPaths, CriticalPaths | None]:
    """The critical paths in the placement's link crossings, and in hand-overs between merged
    agents (None without a merge)."""
    waits = waits_of((a.name, a.waits) for a in spec.agents)
    paths = CriticalPaths(convs, waits, placement.crossings)
    if not placement.merged:
        return paths, None
    return paths, CriticalPaths(convs, waits, lambda a, b: int(placement.are_merged(a, b)))


def _placed_with_peers(placement: Placement, peers: dict[str, tuple[str, ...]]) -> list[str]:
    """A note per agent placed with its ``peers``: where, and beside whom."""
    return [
        f"{name} is not in the record (the specification has grown since the run): placed on "
        f"{placement.label(placement.host_of(name) or 0)} with its peers ({', '.join(peers.get(name, ()))})"
        for name in placement.with_peers
    ]


def unseen_peers(spec: SystemSpec, records: Iterable[TrafficRecord]) -> dict[str, tuple[str, ...]]:
    """The agents of ``spec`` no communicate of ``records`` was sent by or to (the specification
    has grown since the run), each with its peers: the agents at the other end of its
    ``[[channels]]`` (external roles left out), sorted. The ``unseen`` of
    :func:`~services.spec_check.placement.parse_placement`."""
    seen = {name for r in records for name in (r.sender, *r.receivers)}
    agents = spec.agent_names
    return {
        a: tuple(sorted({e for c in spec.channels if a in c.ends for e in c.ends if e != a and e in agents}))
        for a in agents
        if a not in seen
    }


def what_if(
    run_dir: Path,
    spec: SystemSpec,
    placement: Placement,
    rtt_s: float | None,
    roles: Sequence[RoleReplyBy] = (),
    data: RunData | None = None,
) -> WhatIf:
    """Weigh ``placement`` with links of round-trip time ``rtt_s`` (s; None: none given) on the
    record of ``run_dir`` (``data``: that folder as read already), against ``roles``' declared
    reply-by. Raises FileNotFoundError when ``run_dir`` is not a folder, PlacementError when its
    record holds no communicate; what cannot be read in it becomes a note, and so does each
    agent placed with its peers (``Placement.with_peers``)."""
    data = data if data is not None else load_run(run_dir)
    records = [m.rec for m in data.messages]
    if not records:
        raise PlacementError(f"{run_dir}: the record holds no communicates to weigh")
    # the loader tries every content in its language; this tool reads none
    notes = [n for n in data.notes if "not decodable in their language" not in n]
    convs = conversations(data.messages)
    paths, merged = _paths(convs, spec, placement)
    first_t, last_t = min(r.t for r in records), max(r.t for r in records)
    w = WhatIf(run_dir, placement, rtt_s, first_t, last_t, traffic(records, placement), convs, paths,
               merged, list(roles), spec, notes=notes)  # fmt: skip
    w.communicates = len(records)
    w.waits = paths.all_waits()
    w.one_way_s = _one_way_s(records, placement)
    w.measured = _measured(run_dir, placement, first_t, last_t)
    notes += _placed_with_peers(placement, unseen_peers(spec, records))
    if w.traffic.unplaced:
        notes.append(
            f"{w.traffic.unplaced} communicate(s) of agents not placed (outside the platform) left out"
        )
    return w


def size_rows(w: WhatIf) -> list[SizeRow]:
    """The crossing communicates per channel, protocol and performative, with the estimates."""
    sizes: dict[tuple[str, str, str], list[int]] = defaultdict(list)
    for r in w.traffic.crossing:
        sizes[(r.channel, r.protocol or "-", r.performative)].append(r.size)
    estimates = {(c.name, cp.protocol): cp.sizes for c in w.spec.channels for cp in c.protocols}
    return [
        SizeRow(
            channel, protocol, perf, tuple(sorted(found)), estimates.get((channel, protocol), {}).get(perf)
        )
        for (channel, protocol, perf), found in sorted(sizes.items())
    ]
