"""The requirement tree (paper §5.1, Figure 5) read together with the decomposition that
serves it (§5.2, Tables 1–2) and the channels that result (§5.4): which steps and channels
serve each requirement, and which communicates of a run exercise it.

A step serves the requirements it lists (``[[steps]] requirements``) with the channels it
creates (``new_channels``), reallocates (``reallocated``) and supplements (``supplemented``);
a requirement is served by the channels of every step that lists it, each named ``C<k>`` as in
``[[channels]]``, where it joins two agents. A requirement's ``properties``
(:class:`~services.spec.properties.Property`) say what must have happened on those channels
for it to be met; without them, each ``evidence`` statement
(:class:`~services.spec.decomposition.Evidence`) is a property of one step, and without
either, a communicate on each serving channel is (:func:`properties_of`).
:func:`evidence_problems` checks the statements and the properties' steps against the
channels (``roco spec check`` reports them; ``roco spec trace`` refuses a file that has any).
"""

from __future__ import annotations

from dataclasses import dataclass

from services.spec.decomposition import Decomposition, Evidence, Requirement, Step
from services.spec.model import NOT_UNDERSTOOD, ChannelProtocol, ChannelSpec, SystemSpec
from services.spec.properties import EventPattern, Property, property_problems


@dataclass(frozen=True)
class Served:
    """How the decomposition serves one requirement: the ``steps`` (their numbers) that list
    it and the ``channels`` (``C<k>``, in number order) those steps create, reallocate or
    supplement."""

    steps: tuple[int, ...]
    channels: tuple[str, ...]


def _touched(step: Step) -> set[int]:
    """The numbers of the channels ``step`` creates, reallocates or supplements."""
    created = {c.number for c in step.new_channels}
    return created | {c.number for c in step.reallocated} | {c.number for c in step.supplemented}


def served(d: Decomposition) -> dict[str, Served]:
    """Every requirement of ``d`` (by id) and how the steps serve it (no step: empty)."""
    steps: dict[str, list[int]] = {r.id: [] for r in d.requirements}
    numbers: dict[str, set[int]] = {r.id: set() for r in d.requirements}
    for step in d.steps:
        for rid in (r for r in step.requirements if r in steps):
            steps[rid].append(step.number)
            numbers[rid] |= _touched(step)
    return {rid: Served(tuple(steps[rid]), tuple(f"C{n}" for n in sorted(numbers[rid]))) for rid in steps}


def children(d: Decomposition) -> dict[str | None, list[Requirement]]:
    """Each requirement's children in file order; ``None`` maps to the roots."""
    out: dict[str | None, list[Requirement]] = {}
    for r in d.requirements:
        out.setdefault(r.parent, []).append(r)
    return out


def leaves(d: Decomposition) -> list[Requirement]:
    """The requirements no other requirement names as its parent, in file order."""
    parents = {r.parent for r in d.requirements}
    return [r for r in d.requirements if r.id not in parents]


def evidence_of(requirement: Requirement, serving: Served) -> tuple[Evidence, ...]:
    """The communicates that exercise ``requirement``: its own ``evidence``, else one
    communicate on each channel serving it (none when nothing serves it)."""
    if requirement.evidence:
        return requirement.evidence
    return tuple(Evidence(channel=c) for c in serving.channels)


def properties_of(requirement: Requirement, serving: Served) -> tuple[Property, ...]:
    """What must have happened for ``requirement`` to be met: its own ``properties``; else one
    property of one step per ``evidence`` statement (:func:`evidence_of`)."""
    if requirement.properties:
        return requirement.properties
    return tuple(
        Property(
            text=ev.describe(),
            steps=(
                EventPattern(
                    channel=ev.channel,
                    protocol=ev.protocol,
                    performative=ev.performative,
                    content=ev.content,
                    at_least=ev.at_least,
                ),
            ),
        )
        for ev in evidence_of(requirement, serving)
    )


def _as_evidence(step: EventPattern) -> Evidence:
    """The part of ``step`` the channels say something about."""
    return Evidence(
        channel=step.channel,
        protocol=step.protocol,
        performative=step.performative,
        content=step.content,
        at_least=step.at_least,
    )


def evidence_problems(d: Decomposition, spec: SystemSpec) -> list[str]:
    """Every ``evidence`` statement and property step that does not fit the specification, as
    sentences: its channel must serve the requirement and exist; its protocol must be one of
    the channel's; its performative one a role of that protocol may send (or
    ``not-understood``); its content a term the channel lists for that performative;
    ``at_least`` at least 1; and each property as :func:`property_problems` says."""
    serving = served(d)
    channels = {c.name: c for c in spec.channels}
    problems: list[str] = []
    for r in d.requirements:
        for n, ev in enumerate(r.evidence, 1):
            where = f"requirement {r.id}, evidence {n} ({ev.describe()})"
            found = _problems(ev, serving[r.id], channels.get(ev.channel), spec)
            problems += [f"{where}: {p}" for p in found]
        for n, prop in enumerate(r.properties, 1):
            where = f"requirement {r.id}, property {n} ({prop.text})"
            problems += [f"{where}: {p}" for p in property_problems(prop)]
            for k, step in enumerate(prop.steps, 1):
                found = _problems(_as_evidence(step), serving[r.id], channels.get(step.channel), spec)
                problems += [f"{where}, step {k} ({step.describe()}): {p}" for p in found]
    return problems


def _problems(ev: Evidence, serving: Served, channel: ChannelSpec | None, spec: SystemSpec) -> list[str]:
    """What is wrong with one evidence statement (see :func:`evidence_problems`)."""
    if ev.at_least < 1:
        return [f"at_least must be 1 or more, not {ev.at_least}"]
    if channel is None:
        return [f"no channel {ev.channel} in [[channels]]"]
    if ev.channel not in serving.channels:
        steps = ", ".join(map(str, serving.steps)) or "none"
        theirs = ", ".join(serving.channels) or "none"
        return [f"{ev.channel} does not serve it (its steps: {steps}; their channels: {theirs})"]
    protocols = [cp for cp in channel.protocols if ev.protocol in (None, cp.protocol)]
    if not protocols:
        return [f"{ev.channel} has no protocol {ev.protocol}"]
    return _term_problems(ev, protocols, spec)


def _term_problems(ev: Evidence, protocols: list[ChannelProtocol], spec: SystemSpec) -> list[str]:
    """The performative and content term of ``ev`` against the channel's ``protocols``."""
    if ev.performative not in (None, NOT_UNDERSTOOD):
        roles = [spec.protocols[cp.protocol] for cp in protocols]
        if not any(ev.performative in (*r.initiator, *r.participant) for r in roles):
            return [f"no role of {_names(protocols)} on {ev.channel} sends {ev.performative}"]
    if ev.content is None:
        return []
    terms = _terms(ev, protocols)
    if ev.content not in terms:
        listed = ", ".join(sorted(terms)) or "none"
        return [f"{ev.channel} lists no content {ev.content} for it (listed: {listed})"]
    return []


def _terms(ev: Evidence, protocols: list[ChannelProtocol]) -> set[str]:
    """The content terms the channel lists for ``ev``'s performative (any, when None)."""
    terms: set[str] = set()
    for cp in protocols:
        for performative, listed in cp.contents.items():
            if ev.performative in (None, performative):
                terms.update(listed)
    return terms


def _names(protocols: list[ChannelProtocol]) -> str:
    return "/".join(cp.protocol for cp in protocols)
