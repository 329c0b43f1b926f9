"""An agent's protocol roles held against the specification (paper §4 step 4, the agent's
interface; docs/spec.md, "Protocol roles"): the roles the specification gives an agent
(:func:`spec_roles`), a role declared on every channel expanded (:func:`expand_roles`), and
every way declared roles, handlers and code differ from it, one line each
(:func:`role_problems`, :func:`code_problems` with services/runtime/code_scan.py,
:func:`agent_problems`). An agent whose roles differ refuses to start
(services/runtime/roles/dispatch.py); ``roco spec verify-code`` and ``roco spec new-agent``
run the same comparison without starting one.
"""

from __future__ import annotations

import inspect
from collections.abc import Container, Iterable, Sequence
from dataclasses import replace
from pathlib import Path

from services.runtime.code_scan import findings_text, scan
from services.runtime.roles.declare import (
    EVERY_CHANNEL,
    EVERY_NOTICE,
    HandlerKey,
    RoleDecl,
    handler_for,
    handlers_of,
)
from services.spec.model import ChannelSpec, SystemSpec
from services.spec.notices import notice_protocols
from services.spec.protocol_defs import machine_of
from services.spec.render_names import spellings
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Protocol, Role

__all__ = [
    "agent_problems",
    "code_problems",
    "expand_roles",
    "incoming",
    "optional",
    "outgoing",
    "path_to",
    "role_problems",
    "spec_roles",
]


def optional(machine: Protocol, role: Role) -> frozenset[Performative]:
    """Performatives a role handles by itself when the agent writes no handler for them (see
    the module docstring): ``not-understood``; ``agree`` to an initiator; ``cancel`` to a
    participant where the machine follows the cancel meta-protocol (a ``cancelling`` state;
    coordinate's cancel is a request of its own, paper §5.4). Every other performative the
    peer may send needs a handler."""
    out = {Performative.NOT_UNDERSTOOD}
    if role == INITIATOR:
        out.add(Performative.AGREE)
    elif "cancelling" in machine.states:
        out.add(Performative.CANCEL)
    return frozenset(out)


def spec_roles(spec: SystemSpec, agent: str) -> list[RoleDecl]:
    """The roles the specification gives ``agent``: per channel it ends and protocol of that
    channel, initiator or participant, with every language the channel gives the protocol
    (paper §4 step 4, the agent's interface)."""
    out = []
    for ch in spec.channels:
        if agent not in ch.ends:
            continue
        for cp in ch.protocols:
            role: Role = INITIATOR if cp.initiator == agent else PARTICIPANT
            out.append(RoleDecl(ch.name, cp.protocol, role, _languages(ch, cp.protocol)))
    return out


def expand_roles(spec: SystemSpec, agent: str, declared: Iterable[RoleDecl]) -> list[RoleDecl]:
    """``declared`` with each role on :data:`EVERY_CHANNEL` replaced by the same role (its
    reply-by, retransmission and ``unused``) on every channel where the specification gives
    ``agent`` that role of that protocol in exactly those languages, in the specification's
    order; a channel the agent declares that protocol on by itself is left to that declaration.
    A role of :data:`EVERY_NOTICE` stands so for every notice protocol (services/spec/notices.py),
    each made the role of that protocol (``handled_as`` EVERY_NOTICE). A role on EVERY_CHANNEL
    that covers no channel is dropped (:func:`role_problems` names it)."""
    declared = list(declared)
    own = {(d.channel, d.protocol) for d in declared if d.channel != EVERY_CHANNEL}
    given = spec_roles(spec, agent)
    notices = _notices(spec, declared)
    out: list[RoleDecl] = []
    for decl in declared:
        if decl.channel != EVERY_CHANNEL:
            out.append(decl)
            continue
        out += [
            _on(decl, r) for r in given if _covers(decl, r, notices) and (r.channel, r.protocol) not in own
        ]
    return out


def _on(decl: RoleDecl, given: RoleDecl) -> RoleDecl:
    """Role ``decl`` on EVERY_CHANNEL made the role ``given`` of the specification it stands for."""
    if decl.protocol == EVERY_NOTICE:
        return replace(decl, channel=given.channel, protocol=given.protocol, handled_as=EVERY_NOTICE)
    return replace(decl, channel=given.channel)


def _notices(spec: SystemSpec, declared: Sequence[RoleDecl]) -> frozenset[str]:
    """The specification's notice protocols when a role of ``declared`` is on
    :data:`EVERY_NOTICE` (else none: not worked out)."""
    if any(d.protocol == EVERY_NOTICE for d in declared):
        return notice_protocols(spec)
    return frozenset()


def _covers(decl: RoleDecl, given: RoleDecl, notices: Container[str] = ()) -> bool:
    """Whether role ``decl`` on EVERY_CHANNEL stands for ``given``, a role of the specification
    (``notices``: the specification's notice protocols, what :data:`EVERY_NOTICE` stands for)."""
    protocol = given.protocol in notices if decl.protocol == EVERY_NOTICE else given.protocol == decl.protocol
    return protocol and given.role == decl.role and given.languages == tuple(sorted(decl.languages))


def _every_channel_problems(spec: SystemSpec, agent: str, declared: Sequence[RoleDecl]) -> list[str]:
    """The roles on EVERY_CHANNEL in ``declared`` that are declared twice or cover no channel."""
    problems: list[str] = []
    seen: set[tuple[str, str, tuple[str, ...]]] = set()
    given = spec_roles(spec, agent)
    own = {(d.channel, d.protocol) for d in declared if d.channel != EVERY_CHANNEL}
    notices = _notices(spec, declared)
    for decl in declared:
        if decl.channel != EVERY_CHANNEL:
            continue
        key = (decl.protocol, decl.role, tuple(sorted(decl.languages)))
        if key in seen:
            problems.append(f"agent {agent} declares {decl} twice")
            continue
        seen.add(key)
        covered = [r for r in given if _covers(decl, r, notices)]
        if not covered:
            what = "a notice protocol" if decl.protocol == EVERY_NOTICE else decl.protocol
            problems.append(
                f"agent {agent} declares itself {decl}, but no [[channels]] entry makes it the "
                f"{decl.role} of {what} in {', '.join(sorted(decl.languages)) or 'no language'}"
            )
        elif all((r.channel, r.protocol) in own for r in covered):
            problems.append(
                f"agent {agent} declares itself {decl}, but declares each such channel "
                f"({', '.join(r.channel for r in covered)}) by itself: the role on every channel covers none"
            )
    return problems


def _languages(ch: ChannelSpec, protocol: str) -> tuple[str, ...]:
    names: list[str] = []
    for cp in ch.protocols:
        if cp.protocol == protocol:
            for value in cp.languages.values():
                for lang in (value,) if isinstance(value, str) else value:
                    if lang not in names:
                        names.append(lang)
    return tuple(sorted(names))


def incoming(machine: Protocol, role: Role) -> frozenset[Performative]:
    """The performatives the other role may send in ``machine`` (not-understood included)."""
    other = PARTICIPANT if role == INITIATOR else INITIATOR
    out = {p for (_, r, p) in [*machine.transitions, *machine.terminal_transitions] if r == other}
    return frozenset(out | {Performative.NOT_UNDERSTOOD})


def outgoing(machine: Protocol, role: Role) -> frozenset[Performative]:
    """The performatives ``role`` may send in ``machine`` (not-understood included)."""
    out = {p for (_, r, p) in [*machine.transitions, *machine.terminal_transitions] if r == role}
    return frozenset(out | {Performative.NOT_UNDERSTOOD})


def role_problems(
    spec: SystemSpec, agent: str, declared: Sequence[RoleDecl], handlers: Iterable[HandlerKey]
) -> list[str]:
    """Where ``agent``'s declared roles and handlers differ from the specification, one line
    each, naming the spec entry: a role the spec gives it that it does not declare, a role it
    declares that the spec does not give it (no such channel, the agent does not end it, the
    protocol is not on it, or the spec gives it the other role), languages other than the
    channel's, a performative the other role may send with no handler, and a handler for
    something no declared role receives. A role on :data:`EVERY_CHANNEL` counts as one per
    channel it stands for (:func:`expand_roles`); one that stands for no channel is a problem.
    Empty: they agree."""
    where = f"agent {agent}"
    problems = _every_channel_problems(spec, agent, declared)
    declared = expand_roles(spec, agent, declared)
    want = {(r.channel, r.protocol): r for r in spec_roles(spec, agent)}
    channels = {ch.name: ch for ch in spec.channels}
    seen: set[tuple[str, str]] = set()
    for decl in declared:
        key = (decl.channel, decl.protocol)
        entry = f"[[channels]] {decl.channel}"
        if key in seen:
            problems.append(f"{where} declares {decl.protocol} on {decl.channel} twice")
            continue
        seen.add(key)
        ch = channels.get(decl.channel)
        if ch is None:
            problems.append(f"{where} declares {decl}, but the specification has no channel {decl.channel}")
        elif agent not in ch.ends:
            problems.append(
                f"{where} declares {decl}, but {entry} joins {' and '.join(ch.ends)}: no channel "
                f"between {agent} and its peer there"
            )
        elif key not in want:
            problems.append(f"{where} declares {decl}, but {entry} carries no protocol {decl.protocol}")
        elif want[key].role != decl.role:
            problems.append(
                f"{where} declares itself {decl.role} of {decl.protocol} on {decl.channel}, but "
                f"{entry} makes it the {want[key].role}"
            )
        elif tuple(sorted(decl.languages)) != want[key].languages:
            problems.append(
                f"{where}: its {decl.protocol} role on {decl.channel} speaks "
                f"{', '.join(decl.languages) or 'no language'}, but {entry} carries "
                f"{', '.join(want[key].languages)} there"
            )
    for key, role in want.items():
        if key not in seen:
            problems.append(
                f"{where} declares no {role.role} role for {role.protocol} on {role.channel}, which "
                f"[[channels]] {role.channel} gives it (in {', '.join(role.languages)})"
            )
    handlers = list(handlers)
    valid = [d for d in declared if want.get((d.channel, d.protocol)) == _normal(d)]
    problems += [p for d in valid if (p := _resume_problem(spec, agent, d)) is not None]
    problems += [p for d in valid if (p := _confirm_problem(spec, agent, d)) is not None]
    for decl in valid:
        if decl.unused:
            continue
        machine = machine_of(spec, decl.protocol)
        for perf in sorted(
            incoming(machine, decl.role) - optional(machine, decl.role) - _kept_by_role(decl),
            key=lambda p: p.value,
        ):
            if handler_for(handlers, decl, perf) is None:
                problems.append(
                    f"{where} has no handler for {perf.value} received as {decl.role} of "
                    f"{decl.protocol} on {decl.channel} (the state machine of [protocols.{decl.protocol}] "
                    f"lets the {_other(decl.role)} send it)"
                )
    for h in handlers:
        if not any(
            h.protocol in (d.protocol, d.handled_as)
            and h.role == d.role
            and h.channel in (None, d.channel)
            and not d.unused
            and (h.performative is None or h.performative in incoming(machine_of(spec, d.protocol), d.role))
            for d in valid
        ):
            problems.append(f"{where} has a handler for {h}, which no role it declares receives")
    return problems


def code_problems(
    spec: SystemSpec, agent: str, declared: Sequence[RoleDecl], files: Iterable[Path]
) -> list[str]:
    """What in ``files`` (an agent's code) sends outside its declared roles, compares a
    performative, names a performative none of its roles may send, or opens a conversation
    where it is not the initiator (services/runtime/code_scan.py, reading the names of
    services/spec/names.py by ``spec``'s spellings), one line each."""
    declared = expand_roles(spec, agent, declared)
    may_send: set[Performative] = set()
    for decl in declared:
        if decl.protocol in spec.protocols:
            may_send |= outgoing(machine_of(spec, decl.protocol), decl.role)
    opens = frozenset((d.channel, d.protocol) for d in declared if d.role == INITIATOR and not d.unused)
    return findings_text(scan(files, frozenset(may_send), opens, spellings(spec)), agent)


def agent_problems(spec: SystemSpec, agent: str, cls: type, files: Iterable[Path] | None = None) -> list[str]:
    """Every way agent class ``cls`` differs from agent ``agent``'s interface in ``spec``:
    its roles and handlers (:func:`role_problems`) and its code (:func:`code_problems`; the
    module of the class that declares ``ROLES`` unless ``files`` are given). A class that declares no roles
    (``ROLES`` None) is one problem."""
    declared = getattr(cls, "ROLES", None)
    if declared is None:
        return [f"agent {agent}: {cls.__name__} declares no protocol roles (ROLES)"]
    problems = role_problems(spec, agent, declared, handlers_of(cls))
    if files is None:
        owner = next(c for c in cls.__mro__ if "ROLES" in vars(c))
        source = inspect.getsourcefile(owner)
        files = [Path(source)] if source is not None else []
    return problems + code_problems(spec, agent, declared, files)


def _resume_problem(spec: SystemSpec, agent: str, decl: RoleDecl) -> str | None:
    """Why ``decl``'s ``resume_in`` (:attr:`RoleDecl.resume_in`) names no state its protocol
    can take a conversation back in (:meth:`Roles.restore`: a state other than the initial
    one that non-final transitions lead to from it), or None."""
    if decl.resume_in is None:
        return None
    machine = machine_of(spec, decl.protocol)
    can = sorted(s for s in machine.states - machine.final - {machine.initial} if path_to(machine, s))
    if decl.resume_in in can:
        return None
    return (
        f"agent {agent} takes its kept {decl.protocol} conversations on {decl.channel} back in "
        f"{decl.resume_in!r}, which is no state of [protocols.{decl.protocol}] to take one back in "
        f"(one of: {', '.join(can)})"
    )


def _confirm_problem(spec: SystemSpec, agent: str, decl: RoleDecl) -> str | None:
    """Why ``decl``'s ``confirmed_informs`` (:attr:`RoleDecl.confirmed_informs`) does not fit
    its protocol (its participant sends no ``inform``, or its initiator no ``confirm``), or None."""
    if not decl.confirmed_informs:
        return None
    machine = machine_of(spec, decl.protocol)
    if Performative.INFORM in outgoing(machine, decl.role) and Performative.CONFIRM in incoming(
        machine, decl.role
    ):
        return None
    return (
        f"agent {agent} has its {decl.protocol} informs on {decl.channel} confirmed one at a time, "
        f"but in [protocols.{decl.protocol}] the {decl.role} sends no inform or the "
        f"{_other(decl.role)} no confirm"
    )


def _kept_by_role(decl: RoleDecl) -> frozenset[Performative]:
    """What a role handles itself: a role that keeps its subscription open
    (:attr:`RoleDecl.resubscribes`) every answer but the stream's ``inform``; a role whose
    informs are confirmed one at a time (:attr:`RoleDecl.confirmed_informs`) the ``confirm``."""
    if decl.resubscribes:
        return frozenset({Performative.AGREE, Performative.REFUSE, Performative.FAILURE})
    if decl.confirmed_informs:
        return frozenset({Performative.CONFIRM})
    return frozenset()


def _normal(decl: RoleDecl) -> RoleDecl:
    return RoleDecl(decl.channel, decl.protocol, decl.role, tuple(sorted(decl.languages)))


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


def path_to(machine: Protocol, state: str) -> list[tuple[Role, Performative]] | None:
    """The shortest sequence of (sender's role, performative) from the initial state to
    ``state`` by non-terminal transitions, not-understood left out; None when there is none."""
    paths: dict[str, list[tuple[Role, Performative]]] = {machine.initial: []}
    todo = [machine.initial]
    while todo:
        here = todo.pop(0)
        if here == state:
            return paths[here]
        for (source, role, perf), target in machine.transitions.items():
            if source == here and target not in paths and perf is not Performative.NOT_UNDERSTOOD:
                paths[target] = [*paths[here], (role, perf)]
                todo.append(target)
    return None
