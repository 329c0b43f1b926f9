"""``roco spec deadlock``: communication deadlocks of a specification (paper §4 step 3: "while
specifying new communication channels, an analysis targeted at communication deadlocks is
mandatory"). The manual, with what each finding means: docs/spec.md "Deadlocks".

**Conversations.** Each (channel, protocol) is one conversation of its protocol
(:func:`services.spec.protocol_defs.protocols_of`; FIPA SC00026, SC00027, SC00035, the paper's
coordinate declared in the specification, ...), explored breadth first as two communicating
role automata over FIFO input queues bounded by :data:`QUEUE_CAPACITY`, so each trace reported
is a shortest one. Findings: *deadlock* (no step enabled, a role not final), *unspecified
reception* (a queue's head its role can never receive), *late message* (informational: it
reaches an ended role). ``not-understood`` (SC00037 §3.12) is left out unless
``not_understood=True``; then a role sends it only when it has received a communicate since it
last sent one (the rule :func:`services.runtime.protocol_state.judge` holds every agent to), or
in answer to the head of its queue when it cannot take that one (which it takes off);
``cancel`` (SC00026 §2, SC00027 §2, SC00035 §2) is explored like any
other performative.

**Agents.** Each agent's ``waits = [{ serving = "C3:fipa-request", opens = ["C4:fipa-query"] }]``
(``[[agents]]``, read from the raw TOML) makes a wait-for graph; every cycle is a potential
deadlock (a waiting agent is assumed to serve nothing else).

:func:`analyse` gives a typed :class:`DeadlockResult`, :func:`render` the text,
:func:`deadlock_report` both for the CLI (a deadlock found: non-zero exit).
:func:`analyse_library` and :func:`library_report` explore every protocol of
:data:`shared.fipa_codec.protocols.PROTOCOLS` (the eleven of FIPA SC00025's library, SC00026
to SC00036) for ``roco spec deadlock --library``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from services.spec.model import DEFAULT_SPEC, ChannelProtocol, ChannelSpec, SpecError, SystemSpec, load
from services.spec.protocol_defs import protocols_of, read_raw, role_mismatches
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, PROTOCOLS, Protocol, Role

__all__ = [
    "MAX_CYCLES",
    "MAX_STATES",
    "QUEUE_CAPACITY",
    "ChannelResult",
    "DeadlockResult",
    "Finding",
    "GlobalState",
    "Message",
    "ProtocolResult",
    "Step",
    "WaitCycle",
    "WaitEdge",
    "analyse",
    "analyse_library",
    "deadlock_report",
    "explore",
    "library_report",
    "render",
    "wait_cycles",
    "wait_edges",
]

QUEUE_CAPACITY = 2
"""Default capacity of each of the two queues of a conversation."""

MAX_STATES = 200_000
"""Exploration gives up (SpecError) beyond this many product states of one protocol."""

MAX_CYCLES = 1000
"""At most this many wait-for cycles are listed."""

_ROLES: tuple[Role, Role] = (INITIATOR, PARTICIPANT)
Event = Literal["send", "receive"]
FindingKind = Literal["deadlock", "unspecified-reception", "late-message"]


# ------------------------------------------------------------------------------ result types


@dataclass(frozen=True, order=True)
class Message:
    """A message in flight: its performative, and for an ``inform`` whether it is flagged
    terminal (a terminal L_SW report in ``coordinate``)."""

    performative: str
    terminal: bool = False

    def __str__(self) -> str:
        return self.performative + (" (terminal)" if self.terminal else "")


@dataclass(frozen=True)
class GlobalState:
    """A product state: each role's protocol state and the two queues (head first)."""

    initiator: str
    participant: str
    to_participant: tuple[Message, ...]
    to_initiator: tuple[Message, ...]

    def of(self, role: Role) -> str:
        """The protocol state of ``role``."""
        return self.initiator if role == INITIATOR else self.participant

    def inbox(self, role: Role) -> tuple[Message, ...]:
        """The queue ``role`` receives from."""
        return self.to_initiator if role == INITIATOR else self.to_participant


@dataclass(frozen=True)
class Step:
    """One step of a trace: ``role`` sends or receives ``performative`` (``terminal``: a
    terminal inform) and is then in protocol state ``state``."""

    role: Role
    event: Event
    performative: str
    state: str
    terminal: bool = False

    def text(self, names: Mapping[str, str] | None = None) -> str:
        """``initiator sends request -> requested`` (``names`` maps roles to agent names)."""
        who = names.get(self.role, self.role) if names else self.role
        flag = " (terminal)" if self.terminal else ""
        return f"{who} {self.event}s {self.performative}{flag} -> {self.state}"


@dataclass(frozen=True)
class Finding:
    """A deadlock, unspecified reception or late message: the product ``state`` where it
    shows, a shortest ``trace`` from the start there, and ``detail`` (a sentence)."""

    kind: FindingKind
    state: GlobalState
    trace: tuple[Step, ...]
    detail: str


@dataclass(frozen=True)
class ProtocolResult:
    """The exploration of one protocol's conversations.

    ``states``/``transitions``: reachable product states and steps explored;
    ``bound_reached``: some send waited on a full queue, so the exploration is exhaustive
    only up to ``queue_capacity``; ``notes``: disagreements between the state machine and the
    spec's role lists (informational)."""

    protocol: str
    source: str
    queue_capacity: int
    not_understood: bool
    states: int
    transitions: int
    bound_reached: bool
    deadlocks: tuple[Finding, ...]
    unspecified_receptions: tuple[Finding, ...]
    late_messages: tuple[Finding, ...]
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """No deadlock and no unspecified reception."""
        return not self.deadlocks and not self.unspecified_receptions


@dataclass(frozen=True)
class ChannelResult:
    """One protocol on one channel: the agents in the two roles and the protocol's result."""

    channel: str
    protocol: str
    initiator: str
    participant: str
    result: ProtocolResult

    @property
    def names(self) -> dict[str, str]:
        """Role -> agent name."""
        return {INITIATOR: self.initiator, PARTICIPANT: self.participant}


@dataclass(frozen=True)
class WaitEdge:
    """``agent``, serving conversation ``serving`` (``CHANNEL:PROTOCOL``), opens ``opens``
    and waits for ``waits_for``, that conversation's participant."""

    agent: str
    serving: str
    opens: str
    waits_for: str

    def text(self) -> str:
        return f"{self.agent}, serving {self.serving}, opens {self.opens} and waits for {self.waits_for}"


@dataclass(frozen=True)
class WaitCycle:
    """A cycle of the wait-for graph: each edge's ``waits_for`` is the next edge's ``agent``,
    the last one's the first one's."""

    edges: tuple[WaitEdge, ...]

    @property
    def agents(self) -> tuple[str, ...]:
        """The agents of the cycle, in order (the first not repeated)."""
        return tuple(e.agent for e in self.edges)


@dataclass(frozen=True)
class DeadlockResult:
    """The analysis of one specification: per protocol and per channel the conversations,
    the wait-for graph of the agents and its cycles, and the time taken."""

    spec: Path
    queue_capacity: int
    not_understood: bool
    protocols: tuple[ProtocolResult, ...]
    channels: tuple[ChannelResult, ...]
    waits: tuple[WaitEdge, ...]
    cycles: tuple[WaitCycle, ...]
    seconds: float

    @property
    def deadlock_found(self) -> bool:
        """A conversation can deadlock or receive a message it never consumes, or the agents
        can wait for one another in a cycle."""
        return bool(self.cycles) or any(not p.ok for p in self.protocols)

    def protocol(self, name: str) -> ProtocolResult:
        """The result for protocol ``name``; KeyError when the spec names no such protocol."""
        for p in self.protocols:
            if p.protocol == name:
                return p
        raise KeyError(name)


# ------------------------------------------------------------------------- conversations

_Msg = tuple[Performative, bool]
_State = tuple[str, str, tuple[_Msg, ...], tuple[_Msg, ...], bool, bool]
"""Initiator's and participant's protocol states, the queues to the participant and to the
initiator, and whether the initiator and the participant received a communicate since they
last sent one (kept False unless not-understood is explored: only it depends on them)."""
_RawStep = tuple[Role, Event, _Msg, str]


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


class _Roles:
    """The two role automata of a protocol."""

    def __init__(self, protocol: Protocol, not_understood: bool) -> None:
        self.protocol = protocol
        self.not_understood = not_understood
        self.final = protocol.final
        self.sends: dict[tuple[Role, str], list[tuple[_Msg, str]]] = {}
        edges = [
            *((key, target, False) for key, target in protocol.transitions.items()),
            *((key, target, True) for key, target in protocol.terminal_transitions.items()),
        ]
        for (state, role, perf), target, terminal in edges:
            if perf is Performative.NOT_UNDERSTOOD and not not_understood:
                continue
            self.sends.setdefault((role, state), []).append(((perf, terminal), target))
        for options in self.sends.values():
            options.sort(key=lambda o: (o[0][0].value, o[0][1], o[1]))
        self._closure: dict[tuple[Role, str], frozenset[str]] = {}

    def receive(self, role: Role, state: str, msg: _Msg) -> str | None:
        """The state of ``role`` after it takes ``msg`` in ``state``: what the other sent may
        have crossed what ``role`` sent since (:attr:`Protocol.crossing_transitions`)."""
        perf, terminal = msg
        return self.protocol.next_state(state, _other(role), perf, terminal, crossing=True)

    def accepts(self, role: Role, state: str) -> list[_Msg]:
        """What ``role`` can receive in ``state`` (of what the other role ever sends)."""
        sent = {m for (r, _), options in self.sends.items() if r == _other(role) for m, _ in options}
        ok = {m for m in sent if self.receive(role, state, m) is not None}
        return sorted(ok, key=lambda m: (m[0].value, m[1]))

    def closure(self, role: Role, state: str) -> frozenset[str]:
        """``state`` and the states ``role`` reaches from it by its own sends alone."""
        key = (role, state)
        if key not in self._closure:
            seen = {state}
            todo = [state]
            while todo:
                for _, target in self.sends.get((role, todo.pop()), ()):
                    if target not in seen:
                        seen.add(target)
                        todo.append(target)
            self._closure[key] = frozenset(seen)
        return self._closure[key]

    def never_received(self, role: Role, state: str, msg: _Msg) -> bool:
        return all(self.receive(role, s, msg) is None for s in self.closure(role, state))


def _msg(m: _Msg) -> Message:
    return Message(m[0].value, m[1])


def _public(state: _State) -> GlobalState:
    return GlobalState(state[0], state[1], tuple(map(_msg, state[2])), tuple(map(_msg, state[3])))


def _show_msgs(msgs: Iterable[_Msg]) -> str:
    return ", ".join(str(_msg(m)) for m in msgs) or "nothing"


_Key = tuple[Role, str, _Msg]
"""A role, its state, and a message at the head of its queue."""


@dataclass
class _Exploration:
    """The breadth-first exploration of one protocol's conversations (see :func:`explore`),
    state by state (:meth:`visit`): the state's successors, what its queues hold that will
    never be consumed (:meth:`unconsumed`: a late message after a role ended, an unspecified
    reception before), whether it is a deadlock (:meth:`deadlock`), and the new states
    queued (:meth:`enqueue`)."""

    protocol: Protocol
    roles: _Roles
    queue_capacity: int
    max_states: int
    parent: dict[_State, tuple[_State, _RawStep] | None] = field(default_factory=dict)
    todo: deque[_State] = field(default_factory=deque)
    transitions: int = 0
    bound_reached: bool = False
    deadlocks: list[Finding] = field(default_factory=list)
    stuck_heads: set[_Key] = field(default_factory=set)
    unspecified: dict[_Key, Finding] = field(default_factory=dict)
    late: dict[_Key, Finding] = field(default_factory=dict)

    def run(self) -> None:
        start: _State = (self.protocol.initial, self.protocol.initial, (), (), False, False)
        self.parent[start] = None
        self.todo.append(start)
        while self.todo:
            self.visit(self.todo.popleft())

    def trace(self, state: _State) -> tuple[Step, ...]:
        steps: list[Step] = []
        link = self.parent[state]
        while link is not None:
            state, (role, event, (perf, terminal), after) = link
            steps.append(Step(role, event, perf.value, after, terminal))
            link = self.parent[state]
        return tuple(reversed(steps))

    def visit(self, state: _State) -> None:
        local: dict[Role, str] = {INITIATOR: state[0], PARTICIPANT: state[1]}
        queues: dict[Role, tuple[_Msg, ...]] = {PARTICIPANT: state[2], INITIATOR: state[3]}  # by receiver
        successors, blocked = self.successors(state, local, queues)
        self.transitions += len(successors)
        self.bound_reached = self.bound_reached or blocked > 0
        finished = {role: local[role] in self.roles.final for role in _ROLES}
        for role in _ROLES:
            self.unconsumed(state, role, local[role], queues[role], finished=finished[role])
        if not successors and not blocked and not all(finished.values()):
            self.deadlock(state, local, queues, finished)
        for step, nxt in successors:
            self.enqueue(state, step, nxt)

    def successors(
        self, state: _State, local: dict[Role, str], queues: dict[Role, tuple[_Msg, ...]]
    ) -> tuple[list[tuple[_RawStep, _State]], int]:
        """The steps enabled in ``state`` and the states they lead to; the sends blocked by
        a full queue, counted."""
        successors: list[tuple[_RawStep, _State]] = []
        blocked = 0
        heard = {INITIATOR: state[4], PARTICIPANT: state[5]}
        for role in _ROLES:
            inbox = queues[role]
            received = self.roles.receive(role, local[role], inbox[0]) if inbox else None
            stray = bool(inbox) and received is None  # the head: a communicate it cannot take
            queued = len(queues[_other(role)])
            sends, full = self.sends(state, role, local[role], queued, heard=heard[role], stray=stray)
            successors += sends
            blocked += full
            if received is not None:
                nxt = _with(state, role, received, track=self.roles.not_understood)
                successors.append(((role, "receive", inbox[0], received), nxt))
        return successors, blocked

    def sends(
        self, state: _State, role: Role, local: str, queued: int, *, heard: bool, stray: bool
    ) -> tuple[list[tuple[_RawStep, _State]], int]:
        """The sends ``role`` may make in ``local`` with ``queued`` messages in the other's
        queue, and how many a full queue blocks. A not-understood only when the role ``heard``
        something since it last sent, or answering a ``stray`` head of its queue (a
        communicate it cannot take, which the not-understood takes off)."""
        out: list[tuple[_RawStep, _State]] = []
        blocked = 0
        for msg, target in self.roles.sends.get((role, local), ()):
            answers = msg[0] is Performative.NOT_UNDERSTOOD
            if answers and not (heard or stray):
                continue  # nothing received since it last spoke: nothing to not-understand
            if queued >= self.queue_capacity:
                blocked += 1
                continue
            take = answers and stray
            nxt = _with(state, role, target, send=msg, track=self.roles.not_understood, take=take)
            out.append(((role, "send", msg, target), nxt))
        return out, blocked

    def unconsumed(
        self, state: _State, role: Role, local: str, inbox: tuple[_Msg, ...], *, finished: bool
    ) -> None:
        """Every message in the queue of a role that ended is late; the head of the queue of a
        role that has not, one it can never receive, is an unspecified reception (each kept
        once, with its first, shortest, trace)."""
        if finished:
            for msg in dict.fromkeys(inbox):
                if (role, local, msg) not in self.late:
                    self.late[(role, local, msg)] = Finding(
                        "late-message",
                        _public(state),
                        self.trace(state),
                        f"{_msg(msg)} reaches the {role} after it ended in {local!r}",
                    )
        elif inbox and self.roles.never_received(role, local, inbox[0]):
            key = (role, local, inbox[0])
            if key not in self.unspecified:
                accepts = _show_msgs(self.roles.accepts(role, local))
                self.unspecified[key] = Finding(
                    "unspecified-reception",
                    _public(state),
                    self.trace(state),
                    f"{_msg(inbox[0])}, first in the queue of the {role}, can never be received by it: "
                    f"in {local!r} it accepts only {accepts}",
                )

    def deadlock(
        self,
        state: _State,
        local: dict[Role, str],
        queues: dict[Role, tuple[_Msg, ...]],
        finished: dict[Role, bool],
    ) -> None:
        """``state`` enables no step and a role has not ended: what each role waits for."""
        parts = []
        for role in _ROLES:
            inbox = queues[role]
            if finished[role]:
                parts.append(f"the {role} has ended in {local[role]!r}")
                continue
            waits = _show_msgs(self.roles.accepts(role, local[role]))
            text = f"the {role} waits in {local[role]!r} for {waits}"
            if inbox:
                self.stuck_heads.add((role, local[role], inbox[0]))
                text += f" but its queue holds {_show_msgs(inbox)}"
            parts.append(text)
        self.deadlocks.append(Finding("deadlock", _public(state), self.trace(state), "; ".join(parts)))

    def enqueue(self, state: _State, step: _RawStep, nxt: _State) -> None:
        if nxt in self.parent:
            return
        if len(self.parent) >= self.max_states:
            raise SpecError(
                f"protocol {self.protocol.name}: more than {self.max_states} product states with queues "
                f"of {self.queue_capacity}; lower the queue capacity"
            )
        self.parent[nxt] = (state, step)
        self.todo.append(nxt)


def _wait_entry(here: str, entry: object) -> tuple[str, list[str]]:
    """A ``waits`` entry's ``serving`` and ``opens``; SpecError at ``here`` when malformed."""
    if not isinstance(entry, Mapping) or set(entry) != {"serving", "opens"}:
        raise SpecError(f'{here}: expected {{ serving = "CHANNEL:PROTOCOL", opens = [...] }}, not {entry!r}')
    serving, opens = entry["serving"], entry["opens"]
    if not isinstance(serving, str):
        raise SpecError(f'{here}: serving must be a string "CHANNEL:PROTOCOL", not {serving!r}')
    if not (isinstance(opens, list) and opens and all(isinstance(x, str) for x in opens)):
        raise SpecError(f'{here}: opens must be a non-empty list of "CHANNEL:PROTOCOL", not {opens!r}')
    return serving, opens


def _agent_wait_edges(spec: SystemSpec, path: Path, agent: str, waits: object) -> list[WaitEdge]:
    """The wait-for edges of ``agent``'s ``waits`` (None: it declares none), entry by entry."""
    if waits is None:
        return []
    where = f"{path}: agent {agent}: waits"
    if not isinstance(waits, list):
        raise SpecError(f"{where} must be a list of {{ serving = ..., opens = [...] }} tables")
    edges = []
    for i, entry in enumerate(waits, 1):
        here = f"{where} entry {i}"
        serving, opens = _wait_entry(here, entry)
        _conversation(spec, agent, serving, initiates=False, where=f"{here}: serving")
        for ref in opens:
            _, peer = _conversation(spec, agent, ref, initiates=True, where=f"{here}: opens")
            edges.append(WaitEdge(agent, serving, ref, peer))
    return edges


def _channel_of(spec: SystemSpec, agent: str, ref: str, channel_name: str, where: str) -> ChannelSpec:
    """The channel ``channel_name`` of ``spec``, of which ``agent`` is an end; else SpecError."""
    channel: ChannelSpec | None = next((c for c in spec.channels if c.name == channel_name), None)
    if channel is None:
        known = ", ".join(c.name for c in spec.channels)
        raise SpecError(f"{where} {ref!r}: no channel {channel_name!r} (channels: {known})")
    if agent not in channel.ends:
        raise SpecError(
            f"{where} {ref!r}: {agent} is not an end of {channel_name} ({' and '.join(channel.ends)})"
        )
    return channel


def _protocol_lines(r: ProtocolResult, carried: set[str]) -> list[str]:
    """One protocol's states explored and findings; traces in role names when no channel
    carries it (a channel shows them in its agents' names)."""
    source = f" ({r.source})" if r.source else ""
    bound = f"; queue bound {r.queue_capacity} reached" if r.bound_reached else ""
    lines = [f"  {r.protocol}{source}: {r.states} states, {r.transitions} transitions{bound}: {_summary(r)}"]
    for f in (*r.deadlocks, *r.unspecified_receptions):
        if r.protocol in carried:
            lines.append(f"    {_LABEL[f.kind]}: {f.detail}")
        else:
            lines += _finding_lines(f, "    ")
    lines += [f"    {_LABEL[f.kind]}: {f.detail}" for f in r.late_messages]
    lines += [f"    note: {note}" for note in r.notes]
    return lines


def _channel_lines(c: ChannelResult) -> list[str]:
    lines = [
        f"  {c.channel} {c.protocol}: {c.initiator} initiates, {c.participant} participates: "
        f"{c.result.states} states: {_summary(c.result)}"
    ]
    for f in (*c.result.deadlocks, *c.result.unspecified_receptions):
        lines += _finding_lines(f, "    ", c.names)
    return lines


def _agents_lines(result: DeadlockResult) -> list[str]:
    """The wait-for graph: its edges and cycles."""
    lines = [] if result.waits else ["  no waits declared ([[agents]] waits = [...])"]
    lines += [f"  {e.text()}" for e in result.waits]
    for cycle in result.cycles:
        lines.append(f"  CYCLE {' -> '.join((*cycle.agents, cycle.agents[0]))}:")
        lines += [f"    {n}. {e.text()}" for n, e in enumerate(cycle.edges, 1)]
    if result.waits and not result.cycles:
        lines.append("  no cycle")
    return lines


def explore(
    protocol: Protocol,
    *,
    queue_capacity: int = QUEUE_CAPACITY,
    not_understood: bool = False,
    max_states: int = MAX_STATES,
    notes: Sequence[str] = (),
) -> ProtocolResult:
    """Explore the conversations of ``protocol`` breadth first (see the module docstring):
    the two role automata over two FIFO queues of ``queue_capacity`` messages each. Raises
    SpecError beyond ``max_states`` product states."""
    if queue_capacity < 1:
        raise ValueError("queue_capacity must be at least 1")
    x = _Exploration(protocol, _Roles(protocol, not_understood), queue_capacity, max_states)
    x.run()
    return ProtocolResult(
        protocol=protocol.name,
        source=protocol.spec,
        queue_capacity=queue_capacity,
        not_understood=not_understood,
        states=len(x.parent),
        transitions=x.transitions,
        bound_reached=x.bound_reached,
        deadlocks=tuple(x.deadlocks),
        unspecified_receptions=tuple(f for key, f in x.unspecified.items() if key not in x.stuck_heads),
        late_messages=tuple(x.late.values()),
        notes=tuple(notes),
    )


def _with(
    state: _State,
    role: Role,
    target: str,
    *,
    send: _Msg | None = None,
    track: bool = False,
    take: bool = False,
) -> _State:
    """``state`` after ``role`` moves to ``target``, by sending ``send`` or else by receiving
    the head of its queue; ``take``: the send (a not-understood) answers that head, which it
    takes off the queue; ``track``: keep whether each role received since it last sent."""
    s_i, s_p, to_p, to_i, heard_i, heard_p = state
    if role == INITIATOR:
        s_i = target
        if send is not None:
            to_p = (*to_p, send)
        if send is None or take:
            to_i = to_i[1:]
        heard_i = track and send is None
    else:
        s_p = target
        if send is not None:
            to_i = (*to_i, send)
        if send is None or take:
            to_p = to_p[1:]
        heard_p = track and send is None
    return (s_i, s_p, to_p, to_i, heard_i, heard_p)


# ----------------------------------------------------------------------------- agents


def wait_edges(
    path: Path, spec: SystemSpec | None = None, raw: Mapping[str, Any] | None = None
) -> tuple[WaitEdge, ...]:
    """The wait-for edges the agents of specification ``path`` declare with ``waits`` (see
    the module docstring), in the order of the file. Raises SpecError naming the file, the
    agent and the entry when an entry is malformed or names a conversation the agent cannot
    serve (it must be its participant) or open (it must be its initiator)."""
    spec = load(path) if spec is None else spec
    raw = read_raw(path) if raw is None else raw
    edges: list[WaitEdge] = []
    for n, table in enumerate(raw.get("agents", []), 1):
        if not isinstance(table, Mapping):
            continue
        agent = table.get("name", f"#{n}")
        for edge in _agent_wait_edges(spec, path, agent, table.get("waits")):
            if edge not in edges:
                edges.append(edge)
    return tuple(edges)


def _mine(
    carried: list[ChannelProtocol], agent: str, ref: str, *, initiates: bool, where: str
) -> ChannelProtocol:
    """The channel protocol of ``carried`` ``agent`` initiates (``initiates``) or serves; else
    SpecError."""
    mine = [cp for cp in carried if (cp.initiator == agent) == initiates]
    if mine:
        return mine[0]
    other = carried[0].initiator
    if initiates:
        raise SpecError(f"{where} {ref!r}: {other} initiates it, so {agent} cannot open it")
    raise SpecError(
        f"{where} {ref!r}: {agent} initiates it, so it cannot serve it (only its participant can)"
    )


def _conversation(
    spec: SystemSpec, agent: str, ref: str, *, initiates: bool, where: str
) -> tuple[ChannelProtocol, str]:
    """Resolve ``CHANNEL:PROTOCOL`` for ``agent`` as initiator (``initiates``) or participant;
    the channel protocol and the peer."""
    channel_name, sep, protocol = ref.partition(":")
    if not sep or not channel_name or not protocol:
        raise SpecError(f'{where} {ref!r}: expected "CHANNEL:PROTOCOL", e.g. "C3:fipa-request"')
    channel = _channel_of(spec, agent, ref, channel_name, where)
    carried = [cp for cp in channel.protocols if cp.protocol == protocol]
    if not carried:
        known = ", ".join(cp.protocol for cp in channel.protocols)
        raise SpecError(
            f"{where} {ref!r}: {channel_name} carries no protocol {protocol!r} (it carries {known})"
        )
    mine = _mine(carried, agent, ref, initiates=initiates, where=where)
    peer = channel.ends[1] if channel.ends[0] == agent else channel.ends[0]
    return mine, peer


def wait_cycles(edges: Sequence[WaitEdge], *, limit: int = MAX_CYCLES) -> tuple[WaitCycle, ...]:
    """The elementary cycles of the wait-for graph ``edges`` (each listed once, starting at
    its alphabetically first agent; distinct edges between the same agents give distinct
    cycles), shortest first, at most ``limit``."""
    nodes = sorted({e.agent for e in edges} | {e.waits_for for e in edges})
    rank = {n: i for i, n in enumerate(nodes)}
    out_edges: dict[str, list[WaitEdge]] = {n: [] for n in nodes}
    for e in edges:
        out_edges[e.agent].append(e)
    found: list[WaitCycle] = []

    def walk(start: str, node: str, path: list[WaitEdge], seen: set[str]) -> None:
        for e in out_edges[node]:
            if len(found) >= limit:
                return
            if e.waits_for == start:
                found.append(WaitCycle((*path, e)))
            elif rank[e.waits_for] > rank[start] and e.waits_for not in seen:
                walk(start, e.waits_for, [*path, e], seen | {e.waits_for})

    for start in nodes:
        walk(start, start, [], {start})
    return tuple(sorted(found, key=lambda c: (len(c.edges), c.agents)))


# ------------------------------------------------------------------------------- analysis


def analyse(
    path: Path = DEFAULT_SPEC, *, queue_capacity: int = QUEUE_CAPACITY, not_understood: bool = False
) -> DeadlockResult:
    """Analyse specification ``path``: the conversations of every protocol it names, per
    channel, and the agents' wait-for graph (see the module docstring). Raises SpecError
    when the file is invalid."""
    began = time.perf_counter()
    spec = load(path)
    raw = read_raw(path)
    machines = protocols_of(path)
    results = {
        name: explore(
            machine,
            queue_capacity=queue_capacity,
            not_understood=not_understood,
            notes=role_mismatches(machine, spec.protocols[name]),
        )
        for name, machine in machines.items()
    }
    channels = tuple(
        ChannelResult(
            channel=ch.name,
            protocol=cp.protocol,
            initiator=cp.initiator,
            participant=ch.ends[1] if ch.ends[0] == cp.initiator else ch.ends[0],
            result=results[cp.protocol],
        )
        for ch in spec.channels
        for cp in ch.protocols
    )
    edges = wait_edges(path, spec, raw)
    return DeadlockResult(
        spec=path,
        queue_capacity=queue_capacity,
        not_understood=not_understood,
        protocols=tuple(results.values()),
        channels=channels,
        waits=edges,
        cycles=wait_cycles(edges),
        seconds=time.perf_counter() - began,
    )


def _summary(r: ProtocolResult) -> str:
    parts = []
    for count, word in (
        (len(r.deadlocks), "deadlock"),
        (len(r.unspecified_receptions), "unspecified reception"),
        (len(r.late_messages), "late message"),
    ):
        if count:
            parts.append(f"{count} {word}{'s' if count > 1 else ''}")
    return ", ".join(parts) or "no deadlock"


_LABEL = {"deadlock": "DEADLOCK", "unspecified-reception": "UNSPECIFIED RECEPTION", "late-message": "late"}


def _finding_lines(f: Finding, indent: str, names: Mapping[str, str] | None = None) -> list[str]:
    detail = f.detail
    if names:
        for role in _ROLES:
            detail = detail.replace(f"the {role}", f"{names[role]} ({role})")
    lines = [f"{indent}{_LABEL[f.kind]}: {detail}"]
    lines += [f"{indent}  {n}. {step.text(names)}" for n, step in enumerate(f.trace, 1)]
    return lines


def render(result: DeadlockResult) -> str:
    """The analysis as readable text: per protocol the states explored and the findings; per
    channel the deadlocks and unspecified receptions with their shortest traces in the
    agents' names (a protocol no channel carries shows its traces in role names); the
    wait-for graph and its cycles; the verdict and the time taken."""
    nu = "included" if result.not_understood else "left out"
    carried = {c.protocol for c in result.channels}
    lines = [
        f"Deadlock analysis of {result.spec} (paper §4 step 3)",
        f"Conversations: the two roles over FIFO queues of {result.queue_capacity}, explored breadth "
        f"first (shortest traces); cancel included, not-understood {nu}.",
        "",
        "Protocols:",
    ]
    for r in result.protocols:
        lines += _protocol_lines(r, carried)
    lines += ["", "Channels:"]
    for c in result.channels:
        lines += _channel_lines(c)
    lines += ["", "Agents (wait-for graph):", *_agents_lines(result)]
    verdict = "DEADLOCK FOUND" if result.deadlock_found else "no deadlock found"
    lines += ["", f"{verdict} ({result.seconds * 1000:.1f} ms)"]
    return "\n".join(lines) + "\n"


def deadlock_report(path: Path = DEFAULT_SPEC) -> tuple[bool, str]:
    """For ``roco spec deadlock [SPEC]``: (found, text), where ``found`` is True when a
    conversation can deadlock or receive a message it never consumes, or the agents can wait
    for one another in a cycle (the CLI then exits non-zero), and ``text`` is
    :func:`render`'s report. Raises SpecError when the file is invalid."""
    result = analyse(path)
    return result.deadlock_found, render(result)


# -------------------------------------------------------------------------------- library


def analyse_library(
    protocols: Mapping[str, Protocol] | None = None,
    *,
    queue_capacity: int = QUEUE_CAPACITY,
    not_understood: bool = False,
) -> tuple[ProtocolResult, ...]:
    """The conversations of every protocol of ``protocols`` (by default the built-in library,
    :data:`shared.fipa_codec.protocols.PROTOCOLS`), each explored by :func:`explore`, in the
    order given. Raises SpecError as :func:`explore`."""
    chosen = PROTOCOLS if protocols is None else protocols
    return tuple(
        explore(machine, queue_capacity=queue_capacity, not_understood=not_understood)
        for machine in chosen.values()
    )


def library_report(protocols: Mapping[str, Protocol] | None = None) -> tuple[bool, str]:
    """For ``roco spec deadlock --library``: (found, text), where ``found`` is True when a
    conversation of a protocol of ``protocols`` (by default the built-in library) can deadlock
    or receive a message it never consumes, and ``text`` lists per protocol the states
    explored and the findings, with their shortest traces in role names."""
    began = time.perf_counter()
    results = analyse_library(protocols)
    lines = [
        "Deadlock analysis of the built-in interaction protocols (shared/fipa_codec/protocols.py)",
        f"Conversations: the two roles over FIFO queues of {QUEUE_CAPACITY}, explored breadth "
        "first (shortest traces); cancel included, not-understood left out.",
        "",
        "Protocols:",
    ]
    for r in results:
        lines += _protocol_lines(r, set())
    found = any(not r.ok for r in results)
    verdict = "DEADLOCK FOUND" if found else "no deadlock found"
    lines += ["", f"{verdict} ({(time.perf_counter() - began) * 1000:.1f} ms)"]
    return found, "\n".join(lines) + "\n"
