"""``roco spec coverage``: which parts of the specification runs and tests exercised, and
which never were (paper §5.7, §6: the system is verified against its specification; this
says how much of the specification that evidence reached).

The parts (:class:`Item`), each counted from :class:`~services.spec_check.coverage_evidence.Evidence`:

- ``transition``: every transition of each channel's interaction protocols (channel ×
  protocol × (state, sender's role, performative, next state)), the state machines of
  :func:`services.spec.protocol_defs.protocols_of` (FIPA SC00026/27/35 and the paper's
  coordinate, §5.4), the cancel meta-protocol's included; a conversation is followed as
  ``roco spec verify`` follows it (:func:`services.runtime.protocol_state.follow`), and each
  communicate the machine takes in arrival order counts on the transition it took; one taken
  only as crossing another on the wire counts as a crossing, on no transition;
- ``not-understood``: per channel and protocol, a not-understood sent by each role
  (FIPA SC00037 §3.12: allowed in every state after the first, so counted per role, the
  states it was sent in listed);
- ``time-out``: per channel and protocol, a reply-by deadline that passed before the peer
  answered (never on the wire: the agents' FSM records, services/runtime/fsm_record.py);
- ``state``, ``arc``: every state and arc of each agent's FSM (paper §3.2, Tables 3–6), as
  the FSM record of the agent's implementation declares it; an agent with no record has no
  items, and the output says so;
- ``term``: every content term each channel's protocol allows per performative (the
  specification's ``contents``).

Items no evidence reached are listed with why, when ``unexercised.toml`` beside this module
names them (a reason no run or test takes them).
"""

from __future__ import annotations

import fnmatch
import tomllib
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import msgspec

from services.report.load import Message
from services.runtime.fsm_record import FsmDeclared, FsmEntered, Record, TimedOut
from services.runtime.protocol_state import ConversationError, CrossingTracker, follow
from services.spec.model import AgentSpec, ChannelProtocol, SystemSpec, channel_between
from services.spec_check.coverage_evidence import Evidence
from shared.fipa_codec import Performative
from shared.fipa_codec.protocols import (
    INITIATOR,
    PARTICIPANT,
    Protocol,
    ProtocolViolation,
    Role,
    is_terminal_report,
)

Kind = Literal["transition", "not-understood", "time-out", "state", "arc", "term"]
KINDS: dict[Kind, str] = {
    "transition": "protocol transitions",
    "not-understood": "not-understood",
    "time-out": "time-outs",
    "state": "FSM states",
    "arc": "FSM arcs",
    "term": "content terms",
}
"""Each kind of item, as the output names it."""
WHY_FILE = Path(__file__).with_name("unexercised.toml")
MAX_WHY_BYTES = 1024 * 1024
_ABBREV = {INITIATOR: "I", PARTICIPANT: "P"}
TIME_OUT = "time-out: a reply-by passed unanswered"
"""The name of a channel's protocol's time-out item."""


@dataclass(frozen=True, order=True)
class Item:
    """One part of the specification: its ``group`` (``C2 fipa-request`` for a channel's
    protocol, ``a_co`` for an agent's FSM), ``kind`` and ``name`` within the group. Its
    :attr:`key` (``group: name``) is what ``unexercised.toml`` matches."""

    group: str
    kind: Kind
    name: str

    @property
    def key(self) -> str:
        return f"{self.group}: {self.name}"


def edge_name(source: str, role: Role, performative: str, target: str, terminal: bool = False) -> str:
    """``requested -P: refuse-> refused`` (``[terminal]`` after a terminal inform)."""
    flag = " [terminal]" if terminal else ""
    return f"{source} -{_ABBREV[role]}: {performative}{flag}-> {target}"


def arc_name(source: str, target: str, label: str) -> str:
    """``trigger -> procReq (command or cancel)``."""
    return f"{source} -> {target}" + (f" ({label})" if label else "")


class Why(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """One entry of ``unexercised.toml``: item keys (``fnmatch`` patterns) and why neither a
    run nor a test takes them."""

    items: tuple[str, ...]
    why: str


class WhyFile(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    unexercised: tuple[Why, ...] = ()


def read_why(path: Path = WHY_FILE) -> tuple[Why, ...]:
    """The entries of ``path``. Raises ValueError (naming the file) when it is larger than
    :data:`MAX_WHY_BYTES` or malformed, OSError when it cannot be read."""
    if path.stat().st_size > MAX_WHY_BYTES:
        raise ValueError(f"{path}: larger than {MAX_WHY_BYTES} bytes")
    try:
        return msgspec.convert(tomllib.loads(path.read_text(encoding="utf-8")), WhyFile).unexercised
    except (tomllib.TOMLDecodeError, msgspec.ValidationError) as exc:
        raise ValueError(f"{path}: {exc}") from None


# ---------------------------------------------------------------------------------------------
# the items


def protocol_items(group: str, machine: Protocol, cp: ChannelProtocol) -> list[Item]:
    """The items of one channel's protocol: its transitions (not-understood aside), a
    not-understood by each role that the other may send something to, a time-out when the
    participant answers at all (not in a one-message protocol), and its content terms."""
    edges = [
        (s, r, p, t, terminal)
        for table, terminal in ((machine.transitions, False), (machine.terminal_transitions, True))
        for (s, r, p), t in table.items()
        if p is not Performative.NOT_UNDERSTOOD
    ]
    items = [
        Item(group, "transition", edge_name(s, r, p.value, t, terminal)) for s, r, p, t, terminal in edges
    ]
    items += _answer_items(group, {r for _, r, _, _, _ in edges})
    items += [
        Item(group, "term", f"{perf} carries {term}") for perf, terms in cp.contents.items() for term in terms
    ]
    return items


def _answer_items(group: str, senders: set[Role]) -> list[Item]:
    """A not-understood by each role the other sends something to (``senders``: the roles
    that send), and a time-out when the participant answers at all."""
    items = [
        Item(group, "not-understood", f"not-understood by the {role}")
        for role, other in ((INITIATOR, PARTICIPANT), (PARTICIPANT, INITIATOR))
        if other in senders
    ]
    if PARTICIPANT in senders:
        items.append(Item(group, "time-out", TIME_OUT))
    return items


def fsm_items(agent: str, declared: FsmDeclared) -> list[Item]:
    """The states and arcs of ``agent``'s FSM as ``declared``."""
    return [Item(agent, "state", f"state {s}") for s in declared.states] + [
        Item(agent, "arc", arc_name(*a)) for a in declared.arcs
    ]


def reference_fsm(agent: AgentSpec, records: Iterable[Record]) -> FsmDeclared | None:
    """The FSM ``agent``'s implementation declared (the specification's ``implementation``),
    else any declared under its name, else None."""
    found = None
    for r in records:
        if isinstance(r, FsmDeclared) and r.agent == agent.name:
            if r.implementation == agent.implementation:
                return r
            found = found or r
    return found


# ---------------------------------------------------------------------------------------------
# the counting


@dataclass
class Coverage:
    """What :func:`measure` found: every ``item`` in order, how often each was taken
    (``counts``), the protocol states each not-understood and time-out was met in
    (``where``), the agents whose FSM no record declares (``unknown_fsms``), and what could
    not be counted: ``crossings`` (communicates taken only as crossing another),
    ``rejected`` (not allowed by the state machine: ``roco spec verify`` tells which),
    ``outside`` (communicates of no channel's protocol of the specification: tests of other
    specifications, malformed payloads), ``errors`` (returns to the initial state after a
    transition function raised), ``stray`` (FSM entries on no arc of the declared FSM)."""

    spec: str
    evidence: Evidence
    items: list[Item] = field(default_factory=list)
    counts: Counter[Item] = field(default_factory=Counter)
    where: dict[Item, Counter[str]] = field(default_factory=lambda: defaultdict(Counter))
    unknown_fsms: list[str] = field(default_factory=list)
    fsm_of: dict[str, FsmDeclared] = field(default_factory=dict)
    channel_ends: dict[str, tuple[str, str]] = field(default_factory=dict)
    """Each channel's two ends, by channel name (the figure's agent graph)."""
    why: tuple[Why, ...] = ()
    crossings: int = 0
    rejected: int = 0
    outside: int = 0
    errors: Counter[str] = field(default_factory=Counter)
    stray: Counter[str] = field(default_factory=Counter)

    @property
    def exercised(self) -> int:
        return sum(1 for i in self.items if self.counts[i])

    @property
    def share(self) -> float:
        """Exercised items / items (0 when there are none)."""
        return self.exercised / len(self.items) if self.items else 0.0

    def by_kind(self) -> dict[Kind, tuple[int, int]]:
        """(exercised, items) per kind, in :data:`KINDS` order."""
        out: dict[Kind, tuple[int, int]] = {}
        for kind in KINDS:
            mine = [i for i in self.items if i.kind == kind]
            out[kind] = (sum(1 for i in mine if self.counts[i]), len(mine))
        return out

    def transitions(self) -> dict[str, tuple[int, int]]:
        """(taken, transitions) per interaction protocol, whatever the channel (a transition
        counts as taken when any channel's conversation took it), and per agent's FSM its arcs:
        the transitions of the protocols and of the agents' FSMs, the measure of paper §5.7's
        verification at the level of the state machines themselves."""
        taken: dict[str, set[str]] = defaultdict(set)
        every: dict[str, set[str]] = defaultdict(set)
        for i in self.items:
            if i.kind == "transition":
                owner = i.group.split(" ", 1)[1]
            elif i.kind == "arc":
                owner = f"{i.group} FSM"
            else:
                continue
            every[owner].add(i.name)
            if self.counts[i]:
                taken[owner].add(i.name)
        return {owner: (len(taken[owner]), len(names)) for owner, names in every.items()}

    def groups(self) -> dict[str, list[Item]]:
        """The items by group, in order."""
        out: dict[str, list[Item]] = defaultdict(list)
        for i in self.items:
            out[i.group].append(i)
        return dict(out)

    def why_not(self, item: Item) -> str | None:
        """Why ``item`` is never taken, when ``unexercised.toml`` says."""
        for w in self.why:
            if any(fnmatch.fnmatchcase(item.key, pattern) for pattern in w.items):
                return w.why
        return None


Key = tuple[str, frozenset[str]]


@dataclass
class _Conversation:
    tracker: CrossingTracker | None = None
    state: str = ""
    """Where the conversation stands in the plain state machine (arrival order)."""


class _Follower:
    """Follows the conversations of one group of communicates and counts what they took."""

    def __init__(self, spec: SystemSpec, machines: Mapping[str, Protocol], cov: Coverage) -> None:
        self.spec = spec
        self.machines = machines
        self.cov = cov
        self.conversations: dict[Key, _Conversation] = {}

    def take(self, m: Message) -> None:
        rec = m.rec
        where = self._where(m)
        if where is None:
            self.cov.outside += 1
            return
        cp, role, perf, group = where
        machine = self.machines[cp.protocol]
        assert rec.conversation_id is not None and rec.receivers
        key = (rec.conversation_id, frozenset((rec.sender, rec.receivers[0])))
        conv = self.conversations.setdefault(key, _Conversation())
        before = conv.state or machine.initial
        terminal = is_terminal_report(m.comm) if m.comm is not None else None
        try:
            conv.tracker, outcome = follow(conv.tracker, machine, role, perf, terminal=terminal)
        except (ProtocolViolation, ConversationError):
            self.cov.rejected += 1
            return
        self._term(m, cp, group)
        if outcome == "aborted":
            item = Item(group, "not-understood", f"not-understood by the {role}")
            self.cov.counts[item] += 1
            self.cov.where[item][before] += 1
            conv.state = "not-understood"
            return
        if outcome == "forgotten":  # a cancel of a conversation never seen: it crossed its end
            self.cov.crossings += 1
            return
        self._edge(conv, machine, group, (before, role, perf, terminal))

    def _edge(
        self,
        conv: _Conversation,
        machine: Protocol,
        group: str,
        step: tuple[str, Role, Performative, bool | None],
    ) -> None:
        """Count the transition the plain machine takes from ``before``, or a crossing."""
        before, role, perf, terminal = step
        assert conv.tracker is not None
        states = conv.tracker.states
        options = []
        for flag in (False, True) if terminal is None else (terminal,):
            target = machine.next_state(before, role, perf, flag)
            if target is not None:
                used = flag and (before, role, perf) in machine.terminal_transitions
                options.append((target not in states, target, used))
        if not options:
            self.cov.crossings += 1
            conv.state = conv.tracker.state
            return
        _, target, used = min(options)
        self.cov.counts[Item(group, "transition", edge_name(before, role, perf.value, target, used))] += 1
        conv.state = target

    def _term(self, m: Message, cp: ChannelProtocol, group: str) -> None:
        if m.content is not None and type(m.content).__name__ in cp.content_types(m.rec.performative):
            self.cov.counts[
                Item(group, "term", f"{m.rec.performative} carries {type(m.content).__name__}")
            ] += 1

    def _where(self, m: Message) -> tuple[ChannelProtocol, Role, Performative, str] | None:
        """The channel's protocol, the sender's role, the performative and the group of ``m``;
        None when ``m`` is of no channel's protocol of the specification."""
        rec, protocol = m.rec, m.rec.protocol or ""
        if not rec.receivers or rec.conversation_id is None or protocol not in self.machines:
            return None
        sender = self.spec.role_of(rec.sender)
        found = _channel_protocol(
            self.spec, sender, self.spec.role_of(rec.receivers[0]), rec.channel, protocol
        )
        if found is None or rec.performative not in _PERFORMATIVES:
            return None
        channel, cp = found
        role: Role = INITIATOR if cp.initiator == sender else PARTICIPANT
        return cp, role, Performative(rec.performative), f"{channel} {cp.protocol}"


_PERFORMATIVES = frozenset(p.value for p in Performative)


def _channel_protocol(
    spec: SystemSpec, sender: str, receiver: str, channel: str, protocol: str
) -> tuple[str, ChannelProtocol] | None:
    """The channel joining ``sender`` and ``receiver`` when it is ``channel``, and its
    ``protocol``; None when there is none."""
    between = channel_between(spec, sender, receiver)
    if between is None or between.name != channel:
        return None
    cp = next((c for c in between.protocols if c.protocol == protocol), None)
    return None if cp is None else (between.name, cp)


def _count_fsms(cov: Coverage, records: Iterable[Record], groups: Mapping[tuple[str, str], str]) -> None:
    """Count the FSM entries and time-outs of ``records``; ``groups`` maps (agent,
    ``peer|protocol``) to the group of a time-out (``C2 fipa-request``)."""
    for r in records:
        if isinstance(r, FsmEntered) and r.agent in cov.fsm_of:
            _count_entry(cov, r, cov.fsm_of[r.agent])
        elif isinstance(r, TimedOut):
            group = groups.get((r.agent, f"{r.peer}|{r.protocol}"))
            if group is not None:
                item = Item(group, "time-out", TIME_OUT)
                cov.counts[item] += 1
                cov.where[item][r.state or "?"] += 1


def _count_entry(cov: Coverage, r: FsmEntered, declared: FsmDeclared) -> None:
    """Count one FSM entry of an agent whose FSM is ``declared``."""
    if r.how == "error":
        cov.errors[r.agent] += 1
        return
    cov.counts[Item(r.agent, "state", f"state {r.state}")] += 1
    if r.how != "arc":
        return
    arc = (r.source or "", r.state, r.label)
    if arc in {tuple(a) for a in declared.arcs}:
        cov.counts[Item(r.agent, "arc", arc_name(*arc))] += 1
    else:
        cov.stray[r.agent] += 1


def _time_out_groups(spec: SystemSpec) -> dict[tuple[str, str], str]:
    """(agent, ``peer|protocol``) → the group of a time-out of ``agent`` waiting on ``peer``."""
    out = {}
    for ch in spec.channels:
        a, b = ch.ends
        for cp in ch.protocols:
            out[(a, f"{b}|{cp.protocol}")] = out[(b, f"{a}|{cp.protocol}")] = f"{ch.name} {cp.protocol}"
    return out


def measure(
    spec: SystemSpec, machines: Mapping[str, Protocol], evidence: Evidence, why: tuple[Why, ...] = ()
) -> Coverage:
    """The coverage of ``spec`` (its protocols' state machines: ``machines``) by ``evidence``
    (module docstring). ``why``: the entries of ``unexercised.toml``."""
    cov = Coverage(spec.system, evidence, why=why)
    for ch in spec.channels:
        cov.channel_ends[ch.name] = ch.ends
        for cp in ch.protocols:
            cov.items += protocol_items(f"{ch.name} {cp.protocol}", machines[cp.protocol], cp)
    for agent in spec.agents:
        declared = reference_fsm(agent, evidence.fsm)
        if declared is None:
            cov.unknown_fsms.append(agent.name)
            continue
        cov.fsm_of[agent.name] = declared
        cov.items += fsm_items(agent.name, declared)
    for group in evidence.groups:
        follower = _Follower(spec, machines, cov)
        for m in group:
            follower.take(m)
    _count_fsms(cov, evidence.fsm, _time_out_groups(spec))
    return cov


def coverage_of(runs: Iterable[Path], tap: Path | None = None, spec_path: Path | None = None) -> Coverage:
    """The coverage of the specification at ``spec_path`` (None: the shipped one) by run
    folders ``runs`` and tap folder ``tap``. Raises SpecError for a specification that does
    not load, FileNotFoundError for a folder that is not there, ValueError for an
    ``unexercised.toml`` that does not read."""
    from services.spec.model import DEFAULT_SPEC, load
    from services.spec.protocol_defs import protocols_of
    from services.spec_check.coverage_evidence import gather

    path = spec_path or DEFAULT_SPEC
    spec, machines = load(path), protocols_of(path)
    return measure(spec, machines, gather(runs, tap), read_why())
