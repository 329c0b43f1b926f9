"""Interaction protocols declared as data in a specification file (paper §4 step 3: "the
interaction protocol specifies the pattern of communication between the agents").

A ``[protocols.NAME]`` table may carry the protocol's state machine, with the meaning of
:func:`shared.fipa_codec.protocols._build` (the builder of the FIPA SC00025 library in
:mod:`shared.fipa_codec.protocols`)::

    [protocols.ask]
    initial = "start"                            # optional, default "start"
    final = ["refused", "failed", "done"]
    transitions = [                              # [state, sender's role, performative, next state]
      ["start", "initiator", "request", "requested"],
      ["requested", "participant", "refuse", "refused"],
      ["requested", "participant", "agree", "agreed"],
      ["agreed", "participant", "inform", "done"],
      ["agreed", "participant", "failure", "failed"],
    ]
    cancellable = ["requested", "agreed"]        # optional: the cancel meta-protocol (SC00026 §2)
    terminal = []                                # optional: taken by an inform flagged terminal
    crossing = []                                # optional: taken by a communicate that crossed
    description = "..."                          # optional
    spec = "FIPA SC00026"                        # optional: where the protocol comes from
    initiator = ["request", "cancel"]            # optional: what each role may send
    participant = ["agree", "refuse", "failure", "inform"]

FIPA's protocols are built in (:data:`shared.fipa_codec.protocols.PROTOCOLS`; their table
may be empty); the application's are declared (the shipped ``coordinate``, paper §5.4
Figure 8, and ``roco-notify``). ``terminal`` and ``crossing`` are transitions as
``transitions`` are: ``terminal`` ones taken by an ``inform`` that reports a terminal L_SW
state (coordinate's), ``crossing`` ones only by a communicate that crossed the other party's
latest on the wire (:attr:`shared.fipa_codec.protocols.Protocol.crossing_transitions`: the
deadlock explorer takes them, the runtime's follower only for a communicate that does not
answer that latest); a crossing transition joins states the transitions name, where no
transition has its (state, role, performative).

A table that leaves ``initiator`` or ``participant`` out gets what the machine's transitions
(plain, terminal, crossing, the cancel meta-protocol's among them) let that role send, in the
order they first appear, never ``not-understood`` (:func:`role_lists`, called by
:func:`services.spec.model.load`, which fails when that machine breaks a rule or there is
none). A list given is kept: it may narrow a built-in machine (:func:`role_mismatches` says
where the two disagree); a declared machine's transitions must be ones it allows.

``cancellable`` adds, from each state listed, ``cancel`` by the initiator to ``cancelling``,
answered by the participant's ``inform`` (``cancelled``) or ``failure`` (``cancel-failed``),
and crossing transitions out of ``cancelling`` for what the participant may send in a
cancellable state (a final answer ends the conversation, an ``agree`` leaves it cancelling),
each replaced by a transition the table lists there. ``not-understood`` is implicit: either
role may send it in every state after the first that is not final (FIPA SC00037 §3.12), ending
the conversation in the final state ``not-understood``; a table must not list it. A
*one-message* protocol (the initiator's ``inform`` ends it) has no such state; a
not-understood answering its one message ends the conversation as any does
(services/runtime/protocol_state.py :func:`~services.runtime.protocol_state.follow`).

Every rule a table must satisfy, with the error that names it and what to change, is in
docs/spec.md ("Declaring a protocol's state machine"). :func:`protocols_of` gives, for every
protocol a specification names, its declared state machine or else the built-in one.
"""

from __future__ import annotations

import difflib
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import msgspec

from services.spec.model import (
    DEFAULT_SPEC,
    ProtocolRoles,
    SpecError,
    SystemSpec,
    load,
    one_line,
    read_text,
)
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, PROTOCOLS, Protocol, Role, _build

__all__ = [
    "MACHINE_KEYS",
    "TABLE_KEYS",
    "declares_state_machine",
    "machine_of",
    "protocol_from_table",
    "protocols_of",
    "read_raw",
    "role_lists",
    "role_mismatches",
    "sends",
    "streams",
]

MACHINE_KEYS: frozenset[str] = frozenset(
    {"initial", "final", "transitions", "cancellable", "terminal", "crossing"}
)
"""Keys of a ``[protocols.NAME]`` table that declare a state machine."""

TABLE_KEYS: frozenset[str] = MACHINE_KEYS | {"initiator", "participant", "description", "spec"}
"""Every key a ``[protocols.NAME]`` table may carry."""

Edge = tuple[str, Role, Performative, str]


def read_raw(path: Path) -> dict[str, Any]:
    """The specification file as plain TOML data; SpecError naming the file when it cannot
    be read or parsed."""
    try:
        return tomllib.loads(read_text(path))
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path}: {one_line(exc)}") from None


def declares_state_machine(table: Mapping[str, object]) -> bool:
    """True when a ``[protocols.NAME]`` table carries (part of) a state machine."""
    return any(key in table for key in MACHINE_KEYS)


def _check_keys(table: object, where: str) -> None:
    """The table is a table of known keys, with the two a state machine cannot do without."""
    if not isinstance(table, Mapping):
        raise SpecError(f"{where}: expected a table, not {type(table).__name__}")
    unknown = sorted(set(table) - TABLE_KEYS)
    if unknown:
        raise SpecError(
            f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(TABLE_KEYS))}; "
            "remove or rename it"
        )
    if "transitions" not in table:
        raise SpecError(
            f"{where}: a state machine needs 'transitions'; add transitions = "
            "[[state, role, performative, state], ...]"
        )
    if "final" not in table:
        raise SpecError(
            f"{where}: a state machine needs 'final' (the final states); add final = [the states "
            "that end the conversation]"
        )


def _initial_and_final(table: Mapping[str, Any], where: str) -> tuple[str, list[str]]:
    """The initial state (``start`` by default) and the final states, at least one."""
    initial = table.get("initial", "start")
    if not isinstance(initial, str) or not initial:
        raise SpecError(
            f"{where}: 'initial' must be a state name, not {initial!r}; name a state, or leave "
            'it out ("start")'
        )
    final = _names(table["final"], "final", where)
    if not final:
        raise SpecError(f"{where}: 'final' names no state; name the states that end the conversation")
    return initial, final


def _check_cancellable(
    cancellable: list[str],
    states: set[str],
    final: list[str],
    lists: Mapping[str, set[str] | None],
    where: str,
) -> None:
    """Each cancellable state is a non-final state of the machine, and the roles' lists allow
    the cancel meta-protocol's performatives."""
    for state in cancellable:
        if state not in states or state in final:
            raise SpecError(
                f"{where}: cancellable state {state!r} is not a non-final state of the transitions; "
                "name a state the transitions reach that is not final, or take it out of 'cancellable'"
            )
    if cancellable:
        _require(lists, INITIATOR, Performative.CANCEL, where, "the cancel meta-protocol ('cancellable')")
        for perf in (Performative.INFORM, Performative.FAILURE):
            _require(lists, PARTICIPANT, perf, where, "the cancel meta-protocol ('cancellable')")


def _check_group(
    kind: str,
    group: list[tuple[int, Edge]],
    ends: tuple[str, list[str]],
    meta: Mapping[tuple[str, Role, Performative], str],
    where: str,
) -> None:
    """In ``group``: every transition out of the initial state sent by the initiator, no
    second target for the same (state, role, performative), none out of a final state, none
    against the cancel meta-protocol's transitions ``meta`` (``ends``: the initial state and
    the final ones)."""
    initial, final = ends
    seen: dict[tuple[str, Role, Performative], tuple[int, str]] = {}
    for n, edge in group:
        source_state, role, perf, target = edge
        if source_state == initial and role != INITIATOR:
            raise SpecError(
                f"{where}: {kind} {n} {_show(edge)} opens the conversation from the {role}; the "
                "first message is the initiator's (its sender is the initiator): make the role "
                "'initiator', or leave from a later state"
            )
        key = (source_state, role, perf)
        if key in seen and seen[key][1] != target:
            first, other = seen[key]
            raise SpecError(
                f"{where}: {kind} {n} {_show(edge)} conflicts with "
                f"{kind} {first}: the same state, role and performative lead to {other!r} and "
                f"{target!r}; keep one of the two"
            )
        seen.setdefault(key, (n, target))
        if source_state in final:
            raise SpecError(
                f"{where}: {kind} {n} {_show(edge)} leaves the final state {source_state!r}; "
                f"remove it, or take {source_state!r} out of 'final'"
            )
        if meta.get(key, target) != target:
            raise SpecError(
                f"{where}: {kind} {n} {_show(edge)} conflicts with the "
                f"cancel meta-protocol ('cancellable'), which leads there to {meta[key]!r}; "
                "remove it (the meta-protocol adds that transition)"
            )


def _checked_build(
    name: str,
    table: Mapping[str, Any],
    where: str,
    edges: list[tuple[int, Edge]],
    extra: tuple[list[tuple[int, Edge]], list[tuple[int, Edge]]],
    states: tuple[str, list[str], list[str]],
) -> Protocol:
    """The machine built (``extra``: the terminal and the crossing transitions; ``states``:
    initial, final, cancellable), every state reachable and a final state reachable from every
    state."""
    terminal, crossing = extra
    initial, final, cancellable = states
    _check_reachable(initial, final, [*edges, *terminal], cancellable, where)
    try:
        protocol = _build(
            name,
            _text(table, "spec", where),
            _text(table, "description", where),
            [edge for _, edge in edges],
            final,
            cancellable=cancellable,
            terminal_edges=[edge for _, edge in terminal],
            initial=initial,
            crossing_edges=[edge for _, edge in crossing],
        )
    except ValueError as exc:
        text = str(exc).removeprefix(f"protocol {name}: ").removeprefix(f"{name}: ")
        raise SpecError(f"{where}: invalid state machine: {text}") from None
    stuck = _dead_ends(protocol)
    if stuck:
        raise SpecError(
            f"{where}: invalid state machine: no final state can be reached from "
            f"{', '.join(repr(x) for x in stuck)} (only not-understood would end the conversation); "
            "add a transition from it toward a final state, or name it in 'final'"
        )
    return protocol


def _check_reachable(
    initial: str, final: list[str], edges: list[tuple[int, Edge]], cancellable: list[str], where: str
) -> None:
    """The initial state is not final, and every state (the final ones and the cancel
    meta-protocol's included) is reachable from it."""
    if initial in final:
        raise SpecError(
            f"{where}: invalid state machine: the initial state {initial!r} is final; take it out "
            "of 'final', or name another 'initial'"
        )
    successors: dict[str, set[str]] = {}
    states = {initial, *final}
    for _, (source, _, _, target) in edges:
        successors.setdefault(source, set()).add(target)
        states |= {source, target}
    if cancellable:
        for state in cancellable:
            successors.setdefault(state, set()).add("cancelling")
        successors["cancelling"] = successors.get("cancelling", set()) | {"cancelled", "cancel-failed"}
        states |= {"cancelling", "cancelled", "cancel-failed"}
    reached, todo = {initial}, [initial]
    while todo:
        for nxt in successors.get(todo.pop(), ()):
            if nxt not in reached:
                reached.add(nxt)
                todo.append(nxt)
    unreachable = sorted(states - reached)
    if unreachable:
        state = unreachable[0]
        change = "take it out of 'final'" if state in final else "remove the transitions that leave it"
        raise SpecError(
            f"{where}: invalid state machine: state {state!r} is unreachable from {initial!r}; add a "
            f"transition into it from a reachable state, or {change}"
        )


def _table_of(roles: ProtocolRoles) -> dict[str, Any]:
    """A spec's protocol entry as the ``[protocols.NAME]`` table it was read from (the roles'
    lists always, other keys when given)."""
    table: dict[str, Any] = {}
    for key, value in msgspec.structs.asdict(roles).items():
        if key in ("transitions", "terminal", "crossing"):
            value = [list(t) for t in value]
        elif isinstance(value, tuple):
            value = list(value)
        if key in (INITIATOR, PARTICIPANT) or value not in (None, [], ""):
            table[key] = value
    return table


def _no_machine(name: str) -> str:
    """The error for a protocol with neither a declared nor a built-in state machine."""
    return (
        f"protocol {name} declares no state machine ({', '.join(sorted(MACHINE_KEYS))}) and is not "
        f"a built-in protocol ({', '.join(PROTOCOLS)}); declare its state machine in "
        f"[protocols.{name}] (docs/spec.md), or use a built-in protocol"
    )


def _machine(spec: SystemSpec, name: str) -> Protocol:
    """:func:`machine_of`'s machine, built."""
    roles = spec.protocols.get(name)
    if roles is None:
        raise SpecError(f"the specification names no protocol {name!r}; declare it in [protocols.{name}]")
    table = _table_of(roles)
    if declares_state_machine(table):
        return protocol_from_table(name, table)
    if name in PROTOCOLS:
        return PROTOCOLS[name]
    raise SpecError(_no_machine(name))


def _listed(listed: set[str] | None, role: str, perf_name: str, here: str) -> None:
    """The role's ``initiator``/``participant`` list, when the table has it, allows the performative."""
    if listed is not None and perf_name not in listed:
        shown = ", ".join(sorted(listed)) or "nothing"
        raise SpecError(
            f"{here}: the {role} may not send {perf_name!r} ('{role}' lists {shown}); add it to "
            f"'{role}', or change the transition"
        )


def _edge(n: int, entry: object, kind: str, where: str, lists: Mapping[str, set[str] | None]) -> Edge:
    """Entry ``n`` of a list of transitions: [state, role, performative, state]."""
    if not (isinstance(entry, list) and len(entry) == 4 and all(isinstance(x, str) and x for x in entry)):
        raise SpecError(
            f"{where}: {kind} {n} {entry!r}: expected [state, role, performative, state], four names"
        )
    source, role, perf_name, target = entry
    here = f"{where}: {kind} {n} {_show((source, role, perf_name, target))}"
    if role not in (INITIATOR, PARTICIPANT):
        raise SpecError(f"{here}: role {role!r} is neither 'initiator' nor 'participant'; write one of them")
    perf = _performative(perf_name, here)
    _listed(lists[role], role, perf_name, here)
    checked: Role = INITIATOR if role == INITIATOR else PARTICIPANT
    return (source, checked, perf, target)


def _performative(perf_name: str, here: str) -> Performative:
    """A FIPA performative a transition may name (not-understood is implicit)."""
    try:
        perf = Performative(perf_name)
    except ValueError:
        close = difflib.get_close_matches(perf_name, [p.value for p in Performative], n=1)
        hint = f"did you mean {close[0]!r}?" if close else "use one of FIPA SC00037's communicative acts"
        raise SpecError(f"{here}: {perf_name!r} is not a FIPA performative (FIPA SC00037); {hint}") from None
    if perf is Performative.NOT_UNDERSTOOD:
        raise SpecError(
            f"{here}: not-understood is implicit (either role, in every state after the first that "
            "is not final); leave it out"
        )
    return perf


def protocol_from_table(name: str, table: Mapping[str, Any], *, source: str | Path | None = None) -> Protocol:
    """Build protocol ``name`` from its ``[protocols.NAME]`` table (see the module docstring).

    Every transition (plain, terminal or crossing) is checked: four strings, a known role, a
    FIPA performative (FIPA SC00037) that the role's ``initiator``/``participant`` list
    allows when the table has that list, the initiator's out of the initial state, no second
    target for the same (state, role, performative), no transition out of a final state; a
    crossing transition joins states the other transitions name and has no (state, role,
    performative) of a transition's; then the machine itself (the initial state not final,
    every state reachable, a final state reachable from every state;
    :class:`shared.fipa_codec.protocols.Protocol`). Raises
    :class:`services.spec.model.SpecError` naming ``source`` (the file), the protocol and
    the offending entry, and saying what to change (docs/spec.md lists every rule).
    """
    where = f"{source}: protocol {name}" if source is not None else f"protocol {name}"
    _check_keys(table, where)
    lists = {role: _role_list(table, role, where) for role in (INITIATOR, PARTICIPANT)}
    initial, final = _initial_and_final(table, where)
    edges = _edges(table["transitions"], "transition", where, lists)
    if not edges:
        raise SpecError(
            f"{where}: 'transitions' is empty; list at least the opening "
            f'["{initial}", "initiator", performative, state]'
        )
    terminal = _edges(table.get("terminal", []), "terminal transition", where, lists)
    crossing = _edges(table.get("crossing", []), "crossing transition", where, lists)
    cancellable = _names(table.get("cancellable", []), "cancellable", where)
    states = {initial} | set(final)
    for _, (source_state, _, _, target) in [*edges, *terminal]:
        states |= {source_state, target}
    _check_cancellable(cancellable, states, final, lists, where)
    meta = _cancel_meta(cancellable)
    _check_group("transition", edges, (initial, final), meta, where)
    _check_group("terminal transition", terminal, (initial, final), {}, where)
    _check_group("crossing transition", crossing, (initial, final), {}, where)
    if cancellable:
        states |= {"cancelling", "cancelled", "cancel-failed"}
    _check_crossing(crossing, edges, meta, states, where)
    return _checked_build(name, table, where, edges, (terminal, crossing), (initial, final, cancellable))


def _check_crossing(
    crossing: list[tuple[int, Edge]],
    edges: list[tuple[int, Edge]],
    meta: Mapping[tuple[str, Role, Performative], str],
    states: set[str],
    where: str,
) -> None:
    """Each crossing transition joins ``states`` (those the other transitions name, the cancel
    meta-protocol's included) and is taken only where no transition is: no transition of
    ``edges`` nor of the cancel meta-protocol (``meta``) has its (state, role, performative)."""
    plain = {(source, role, perf): n for n, (source, role, perf, _) in edges}
    for n, edge in crossing:
        source, role, perf, target = edge
        here = f"{where}: crossing transition {n} {_show(edge)}"
        for state in (source, target):
            if state not in states:
                raise SpecError(
                    f"{here}: {state!r} is no state of the transitions; a crossing transition joins "
                    "states the transitions name: name one of them, or add a transition into it"
                )
        key = (source, role, perf)
        if key in plain:
            raise SpecError(
                f"{here} is also transition {plain[key]}: a crossing transition is taken only where "
                "no transition is (by a communicate that crossed the other party's latest); remove "
                "one of the two"
            )
        if key in meta:
            raise SpecError(
                f"{here} is also a transition of the cancel meta-protocol ('cancellable'), which "
                f"leads there to {meta[key]!r}; remove it"
            )


def protocols_of(path: Path = DEFAULT_SPEC) -> dict[str, Protocol]:
    """Every protocol specification ``path`` names, by name, in the order of the file: the
    state machine its ``[protocols.NAME]`` table declares, or else the built-in one of
    :data:`shared.fipa_codec.protocols.PROTOCOLS` (FIPA SC00026, SC00027, SC00035, ...; the
    paper's ``coordinate`` is declared in the shipped file). Raises SpecError when the file is invalid
    (:func:`services.spec.model.load`), a declared machine is malformed, or a protocol has
    neither."""
    spec = load(path)
    tables = read_raw(path).get("protocols", {})
    out: dict[str, Protocol] = {}
    for name in spec.protocols:
        table = tables.get(name, {})
        if isinstance(table, Mapping) and declares_state_machine(table):
            out[name] = protocol_from_table(name, table, source=path)
        elif name in PROTOCOLS:
            if isinstance(table, Mapping):
                unknown = sorted(set(table) - TABLE_KEYS)
                if unknown:
                    raise SpecError(
                        f"{path}: protocol {name}: unknown key(s) {', '.join(unknown)}; "
                        f"known: {', '.join(sorted(TABLE_KEYS))}; remove or rename it"
                    )
            out[name] = PROTOCOLS[name]
        else:
            raise SpecError(f"{path}: {_no_machine(name)}")
    return out


_MACHINES: dict[int, tuple[SystemSpec, dict[str, Protocol]]] = {}
"""Per loaded specification (by identity; the spec is kept in the value so that a reused id
never matches), the state machines built so far."""


def machine_of(spec: SystemSpec, name: str) -> Protocol:
    """The state machine of protocol ``name`` in ``spec``: the one its ``[protocols.NAME]``
    table declares (see the module docstring), else the built-in one of
    :data:`shared.fipa_codec.protocols.PROTOCOLS`. Built once per specification. Raises
    SpecError when the spec does not name the protocol, its machine is malformed, or it has
    neither."""
    held = _MACHINES.get(id(spec))
    if held is None or held[0] is not spec:
        held = (spec, {})
        _MACHINES[id(spec)] = held
    machines = held[1]
    if name not in machines:
        machines[name] = _machine(spec, name)
    return machines[name]


_STREAMS: dict[int, tuple[Protocol, bool]] = {}
"""Memo of :func:`streams` by machine identity (the machine is kept, so a reused id never matches)."""


def streams(machine: Protocol) -> bool:
    """True when the participant may answer one opening many times: some transition it sends
    lies on a cycle of the machine (fipa-subscribe's informs, coordinate's reports), the
    cancel meta-protocol and not-understood left out. Computed once per machine (the
    runtime asks at every send that awaits a reply)."""
    held = _STREAMS.get(id(machine))
    if held is None or held[0] is not machine:
        held = (machine, _streams(machine))
        _STREAMS[id(machine)] = held
    return held[1]


def _streams(machine: Protocol) -> bool:
    edges = [
        (source, target, role)
        for (source, role, perf), target in [
            *machine.transitions.items(),
            *machine.terminal_transitions.items(),
        ]
        if perf is not Performative.NOT_UNDERSTOOD and "cancelling" not in (source, target)
    ]
    successors: dict[str, set[str]] = {}
    for source, target, _ in edges:
        successors.setdefault(source, set()).add(target)

    def reaches(start: str, goal: str) -> bool:
        seen, todo = {start}, [start]
        while todo:
            for nxt in successors.get(todo.pop(), ()):
                if nxt == goal:
                    return True
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return False

    return any(
        role == PARTICIPANT and (source == target or reaches(target, source))
        for source, target, role in edges
    )


def sends(machine: Protocol, role: Role) -> tuple[str, ...]:
    """The performatives ``machine``'s transitions let ``role`` send: plain, terminal and
    crossing (the cancel meta-protocol's are among the plain ones), each once, in the order
    they first appear there; ``not-understood`` left out (always allowed, FIPA SC00037
    §3.12)."""
    found: dict[str, None] = {}
    for table in (machine.transitions, machine.terminal_transitions, machine.crossing_transitions):
        for _, sender, perf in table:
            if sender == role and perf is not Performative.NOT_UNDERSTOOD:
                found.setdefault(perf.value, None)
    return tuple(found)


def role_lists(
    name: str, table: Mapping[str, Any], *, source: str | Path | None = None
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """What the initiator and the participant of protocol ``name`` may send by its state
    machine (:func:`sends`): the one its ``[protocols.NAME]`` table declares, else the built-in
    one of :data:`shared.fipa_codec.protocols.PROTOCOLS`; the lists a table that leaves them
    out gets (:func:`services.spec.model.load`). Raises SpecError naming ``source`` (the
    file) when the declared machine breaks a rule (:func:`protocol_from_table`) or there is
    no machine."""
    if declares_state_machine(table):
        machine = protocol_from_table(name, table, source=source)
    elif name in PROTOCOLS:
        machine = PROTOCOLS[name]
    else:
        raise SpecError(f"{source}: {_no_machine(name)}" if source is not None else _no_machine(name))
    return sends(machine, INITIATOR), sends(machine, PARTICIPANT)


def role_mismatches(protocol: Protocol, roles: ProtocolRoles) -> list[str]:
    """Where a protocol's state machine and the spec's role lists disagree, as sentences:
    performatives a role may send by its list that no transition allows (a
    protocol state would refuse them), and performatives a transition (plain, terminal or
    crossing) lets a role send that its list does not name (the runtime's check against the
    spec would reject them). ``not-understood`` is left out: it is always allowed."""
    out: list[str] = []
    machine = {role: set(sends(protocol, role)) for role in (INITIATOR, PARTICIPANT)}
    for role, listed in ((INITIATOR, roles.initiator), (PARTICIPANT, roles.participant)):
        declared = set(listed) - {Performative.NOT_UNDERSTOOD.value}
        only_list = sorted(declared - machine[role])
        only_machine = sorted(machine[role] - declared)
        if only_list:
            out.append(
                f"{protocol.name}: the {role} may send {_perfs(only_list)} by the spec's list, but no "
                "transition of the state machine allows it (the protocol state would refuse it)"
            )
        if only_machine:
            out.append(
                f"{protocol.name}: the state machine lets the {role} send {_perfs(only_machine)}, which "
                f"protocols.{protocol.name}.{role} does not list (the runtime would reject it)"
            )
    return out


def _dead_ends(protocol: Protocol) -> list[str]:
    """States from which no final state but ``not-understood`` can be reached without
    ``not-understood`` (which ``_build`` adds from every state, so that Protocol's own check
    never fails on this)."""
    ends = set(protocol.final) - {"not-understood"}
    predecessors: dict[str, set[str]] = {}
    for (source, _, perf), target in [*protocol.transitions.items(), *protocol.terminal_transitions.items()]:
        if perf is not Performative.NOT_UNDERSTOOD:
            predecessors.setdefault(target, set()).add(source)
    reach = set(ends)
    todo = list(ends)
    while todo:
        for source in predecessors.get(todo.pop(), ()):
            if source not in reach:
                reach.add(source)
                todo.append(source)
    return sorted(protocol.states - reach - {"not-understood"})


def _cancel_meta(cancellable: Sequence[str]) -> dict[tuple[str, Role, Performative], str]:
    """The transitions ``_build`` adds for the cancel meta-protocol (its crossing transitions
    out of ``cancelling`` left out: a table's own take their place)."""
    if not cancellable:
        return {}
    meta: dict[tuple[str, Role, Performative], str] = {
        (state, INITIATOR, Performative.CANCEL): "cancelling" for state in cancellable
    }
    meta[("cancelling", PARTICIPANT, Performative.INFORM)] = "cancelled"
    meta[("cancelling", PARTICIPANT, Performative.FAILURE)] = "cancel-failed"
    return meta


def _perfs(names: Sequence[str]) -> str:
    return ", ".join(repr(n) for n in names)


def _show(edge: tuple[str, str, Performative | str, str]) -> str:
    source, role, perf, target = edge
    return "[" + ", ".join(f'"{x}"' for x in (source, role, str(perf), target)) + "]"


def _text(table: Mapping[str, Any], key: str, where: str) -> str:
    value = table.get(key, "")
    if not isinstance(value, str):
        raise SpecError(f"{where}: '{key}' must be a string")
    return value


def _names(value: object, key: str, where: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(x, str) and x for x in value):
        raise SpecError(f"{where}: '{key}' must be a list of state names, not {value!r}")
    return list(value)


def _role_list(table: Mapping[str, Any], role: str, where: str) -> set[str] | None:
    if role not in table:
        return None
    value = table[role]
    if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
        raise SpecError(f"{where}: '{role}' must be a list of performatives, not {value!r}")
    return set(value)


def _require(
    lists: Mapping[str, set[str] | None], role: str, perf: Performative, where: str, why: str
) -> None:
    listed = lists[role]
    if listed is not None and perf.value not in listed:
        raise SpecError(
            f"{where}: {why} lets the {role} send {perf.value!r}, which '{role}' does not list; add "
            f"it to '{role}', or drop 'cancellable'"
        )


def _edges(
    value: object, kind: str, where: str, lists: Mapping[str, set[str] | None]
) -> list[tuple[int, Edge]]:
    """Parse a list of [state, role, performative, state] entries, numbered from 1."""
    plural = kind.split()[0] if kind.startswith(("terminal", "crossing")) else "transitions"
    if not isinstance(value, list):
        raise SpecError(f"{where}: '{plural}' must be a list of [state, role, performative, state]")
    return [(n, _edge(n, entry, kind, where, lists)) for n, entry in enumerate(value, 1)]
