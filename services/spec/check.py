"""``roco spec check``: the decomposition is sound and the agents' interfaces match the
channels (paper §4 steps 2 and 4).

Decomposition rules (paper §4 step 2): the requirements form one tree; every step splits one
group of the current fringe into two new groups (or only supplements channels); every channel
of a split group is reallocated to one of the two new groups (a channel left at a group that no
longer exists is an error); new channels are numbered 1, 2, 3, ... in order of creation and
join groups of the fringe (or one group of the fringe and one group outside the system that
a step declares ``outside``: agents of other platforms, docs/gateway.md); the stop condition holds:
every requirement is addressed by a step, and the final fringe is exactly the groups the agents
substitute, with the final channels exactly the specification's channels C1..Cn between those
agents; each group outside the system is substituted by an external role (``[[externals]]``),
never by an agent. A requirement's ``evidence`` (the communicates that exercise it in a run)
names channels that serve it, with their protocols, performatives and content terms
(services/spec/requirements.py).

Interface rules (paper §4 steps 3–4): every protocol has a state machine, the one its
``[protocols.NAME]`` table declares or a built-in one (services/spec/protocol_defs.py checks a
declared one; docs/spec.md lists its rules); every channel protocol exists and is initiated
by one of the channel's ends; every performative a role may send has a language (not-understood and
cancel excepted), every language exists; the content schemas named for a performative are
terms of its language and the size estimates are sound intervals; every agent ends at
least one channel.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from services.spec.decomposition import Decomposition, NewChannel, Reallocation, Step, load_decomposition
from services.spec.model import (
    DEFAULT_SPEC,
    ChannelProtocol,
    ChannelSpec,
    SpecError,
    SystemSpec,
    interface,
    load,
)
from services.spec.requirements import evidence_problems
from shared.fipa_codec.languages.base import Language

_NO_LANGUAGE = frozenset({"not-understood", "cancel"})


def check_decomposition(d: Decomposition, spec: SystemSpec | None = None) -> list[str]:
    """Every violation of the decomposition rules (see module docstring), as sentences."""
    problems = _tree_problems(d)
    if not d.steps:
        return [*problems, "no decomposition steps"]
    replay = _Replay(d.system, {r.id for r in d.requirements})
    for n, step in enumerate(d.steps, 1):
        problems += replay.take(step, n)
    problems += replay.stop_problems([r.id for r in d.requirements])
    if spec is not None:
        problems += _final_matches_spec(replay.fringe, replay.channels, spec, replay.outside)
        problems += evidence_problems(d, spec)
    return problems


def _tree_problems(d: Decomposition) -> list[str]:
    """The requirements form one tree: unique ids, one root, known parents, no cycle."""
    problems = _id_problems(d)
    parent = {r.id: r.parent for r in d.requirements}
    for req in d.requirements:
        if req.parent is not None and req.parent not in parent:
            problems.append(f"requirement {req.id}: its parent {req.parent} does not exist")
        if _in_cycle(req.id, parent):
            problems.append(f"requirement {req.id} is its own ancestor")
    return problems


def _id_problems(d: Decomposition) -> list[str]:
    """Requirement ids defined twice; a tree without exactly one root."""
    ids = [r.id for r in d.requirements]
    problems = [
        f"requirement {i} is defined more than once" for i in sorted({x for x in ids if ids.count(x) > 1})
    ]
    roots = [r.id for r in d.requirements if r.parent is None]
    if len(roots) != 1:
        problems.append(f"the requirement tree needs exactly one root, not {len(roots)} ({', '.join(roots)})")
    return problems


def _in_cycle(start: str, parent: dict[str, str | None]) -> bool:
    """Following ``parent`` from ``start`` comes back to a requirement already passed."""
    seen: set[str] = set()
    node: str | None = start
    while node is not None and node in parent and node not in seen:
        seen.add(node)
        node = parent[node]
    return node is not None and node in seen


@dataclass
class _Replay:
    """The decomposition replayed step by step (paper §4 step 2): the ``fringe`` of groups,
    the groups ``outside`` the system, every group name ``used``, the ``channels`` by number
    with their two ends, and the first step that ``addressed`` each requirement."""

    system: str
    known: set[str]
    fringe: list[str] = field(default_factory=list)
    outside: list[str] = field(default_factory=list)
    used: set[str] = field(default_factory=set)
    channels: dict[int, tuple[str, str]] = field(default_factory=dict)
    addressed: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.fringe = [self.system]
        self.used = {self.system}

    def take(self, step: Step, n: int) -> list[str]:
        """Apply step ``step``, the ``n``-th; the rules it breaks."""
        where = f"step {step.number}"
        problems: list[str] = []
        if step.number != n:
            problems.append(f"{where}: steps must be numbered 1, 2, 3, ...; expected {n}")
        problems += self._address(step, where)
        if step.split is not None or step.into is not None:
            problems += self._split(step, where)
        elif not step.new_channels and not step.supplemented:
            problems.append(f"{where}: neither splits a group nor creates or supplements a channel")
        problems += self._outside(step, where)
        self._move_channels(step)
        for c in step.new_channels:
            problems += self._new_channel(c, where)
        for sup in step.supplemented:
            if sup.number not in self.channels:
                problems.append(f"{where}: supplements C{sup.number}, which does not exist")
        return problems

    def _address(self, step: Step, where: str) -> list[str]:
        """Note the requirements ``step`` addresses; those that do not exist."""
        for rid in step.requirements:
            self.addressed.setdefault(rid, step.number)
        return [
            f"{where}: addresses unknown requirement {rid}"
            for rid in step.requirements
            if rid not in self.known
        ]

    def _outside(self, step: Step, where: str) -> list[str]:
        """The new groups outside the system that ``step`` declares."""
        problems = []
        for group in step.outside:
            if group in self.used:
                problems.append(f"{where}: the group outside the system {group!r} must be a new group")
            self.outside.append(group)
            self.used.add(group)
        return problems

    def _move_channels(self, step: Step) -> None:
        """Move the ends ``step`` reallocates from the split group."""
        for r in step.reallocated:
            if r.number in self.channels and r.from_ in self.channels[r.number]:
                old = self.channels[r.number]
                self.channels[r.number] = (r.to, old[1]) if old[0] == r.from_ else (old[0], r.to)

    def _split(self, step: Step, where: str) -> list[str]:
        """A split of one fringe group into two new ones, its channels reallocated."""
        if step.split is None or step.into is None:
            return [f"{where}: a split needs both 'split' and 'into'"]
        if step.split not in self.fringe:
            return [
                f"{where}: splits group {step.split!r}, which is not in the fringe ({', '.join(self.fringe)})"
            ]
        problems: list[str] = []
        a, b = step.into
        if a == b or a in self.used or b in self.used:
            problems.append(f"{where}: {step.split} must split into two new groups, not {a!r} and {b!r}")
        if set(step.tasks) != {a, b}:
            problems.append(f"{where}: give the tasks of exactly {a} and {b}")
        problems += self._reallocation_problems(step.split, (a, b), step.reallocated, where)
        pos = self.fringe.index(step.split)
        self.fringe = [*self.fringe[:pos], a, b, *self.fringe[pos + 1 :]]
        self.used |= {a, b}
        return problems

    def _reallocation_problems(
        self, split: str, into: tuple[str, str], moved: tuple[Reallocation, ...], where: str
    ) -> list[str]:
        """Every channel of the ``split`` group moves to one of the two new groups ``into``."""
        a, b = into
        problems = []
        reallocated = {r.number for r in moved}
        for k, ends in sorted(self.channels.items()):
            if split in ends and k not in reallocated:
                problems.append(
                    f"{where}: channel C{k} ends at {split!r}, which this step splits "
                    f"into {a} and {b}; reallocate it to one of them"
                )
        for r in moved:
            current = self.channels.get(r.number)
            if current is None:
                problems.append(f"{where}: reallocates C{r.number}, which does not exist yet")
            elif r.from_ != split or r.from_ not in current:
                problems.append(
                    f"{where}: C{r.number} can only move from the split group {split!r} "
                    f"(its ends are {current[0]} and {current[1]})"
                )
            elif r.to not in into:
                problems.append(f"{where}: C{r.number} must move to {a} or {b}, not {r.to!r}")
        return problems

    def _new_channel(self, c: NewChannel, where: str) -> list[str]:
        """A new channel, numbered next, between two groups of the fringe (or one outside)."""
        problems: list[str] = []
        expected = max(self.channels, default=0) + 1
        if c.number != expected:
            problems.append(f"{where}: new channel C{c.number} should be numbered C{expected}")
        if all(end in self.outside for end in c.ends):
            problems.append(f"{where}: new channel C{c.number} joins two groups outside the system")
        for end in c.ends:
            if end not in self.fringe and end not in self.outside:
                problems.append(
                    f"{where}: new channel C{c.number} ends at {end!r}, which is not in the fringe "
                    f"({', '.join(self.fringe)})"
                )
        if c.ends[0] == c.ends[1]:
            problems.append(f"{where}: new channel C{c.number} joins {c.ends[0]} to itself")
        self.channels[c.number] = c.ends
        return problems

    def stop_problems(self, ids: list[str]) -> list[str]:
        """The stop condition: every requirement addressed, every channel between groups that
        still exist."""
        problems = [
            f"stop condition: requirement {rid} is addressed by no step"
            for rid in ids
            if rid not in self.addressed
        ]
        for k, ends in sorted(self.channels.items()):
            for end in ends:
                if end not in self.fringe and end not in self.outside:
                    problems.append(
                        f"channel C{k} ends at group {end!r}, which no longer exists "
                        f"(fringe: {', '.join(self.fringe)})"
                    )
        return problems


def _final_matches_spec(
    fringe: list[str], channels: dict[int, tuple[str, str]], spec: SystemSpec, outside: list[str]
) -> list[str]:
    """The final fringe is the agents' groups, the groups outside the system the external
    roles', and the channels the specification's."""
    agent_of = {a.group: a.name for a in spec.agents}
    problems = _external_problems(spec, outside, agent_of)
    for g in fringe:
        if g not in agent_of:
            problems.append(f"stop condition: group {g!r} of the final fringe is substituted by no agent")
    for a in spec.agents:
        if a.group not in fringe:
            problems.append(f"agent {a.name} substitutes group {a.group!r}, which is not in the final fringe")
    return problems + _channel_problems(channels, spec, agent_of)


def _external_problems(spec: SystemSpec, outside: list[str], agent_of: dict[str, str]) -> list[str]:
    """Each group outside the system is an external role's, never an agent's; adds the
    external roles to ``agent_of`` (group → who substitutes it)."""
    problems = []
    for e in spec.externals:
        if e.group not in outside:
            problems.append(
                f"external role {e.name} substitutes group {e.group!r}, which no step declares outside"
            )
        elif e.group in agent_of:
            problems.append(
                f"group {e.group!r} outside the system is substituted by agent {agent_of[e.group]}"
            )
        agent_of.setdefault(e.group, e.name)
    for g in outside:
        if g not in agent_of:
            problems.append(f"group {g!r} outside the system is substituted by no external role")
    return problems


def _channel_problems(
    channels: dict[int, tuple[str, str]], spec: SystemSpec, agent_of: dict[str, str]
) -> list[str]:
    """The decomposition's channels are the specification's, between the same ends."""
    problems = []
    by_name = {c.name: c for c in spec.channels}
    for k, ends in sorted(channels.items()):
        name = f"C{k}"
        want = {agent_of.get(e, f"<group {e}>") for e in ends}
        ch = by_name.get(name)
        if ch is None:
            problems.append(f"channel {name} of the decomposition is not specified in [[channels]]")
        elif set(ch.ends) != want:
            problems.append(
                f"channel {name} joins {' and '.join(sorted(want))} by the decomposition, "
                f"but {' and '.join(ch.ends)} in [[channels]]"
            )
    created = {f"C{k}" for k in channels}
    problems += [
        f"channel {c.name} in [[channels]] was created by no decomposition step"
        for c in spec.channels
        if c.name not in created
    ]
    return problems


def check_interfaces(spec: SystemSpec) -> list[str]:
    """Every violation of the interface rules (see module docstring), as sentences."""
    from shared.fipa_codec.languages import load_all

    languages = load_all()
    problems = _machine_problems(spec)
    for ch in spec.channels:
        for cp in ch.protocols:
            problems += _protocol_problems(spec, ch, cp, languages)
    return problems + _end_problems(spec)


def _machine_problems(spec: SystemSpec) -> list[str]:
    """Every protocol of ``[protocols]`` has a state machine: the one its table declares
    (checked by services/spec/protocol_defs.py, whose error says what to change), else a
    built-in one."""
    from services.spec.protocol_defs import machine_of

    problems = []
    for name in spec.protocols:
        try:
            machine_of(spec, name)
        except SpecError as exc:
            problems.append(str(exc))
    return problems


def _protocol_problems(
    spec: SystemSpec, ch: ChannelSpec, cp: ChannelProtocol, languages: Mapping[str, Language]
) -> list[str]:
    """One protocol of one channel: declared (its state machine is checked once per protocol,
    :func:`_machine_problems`), initiated by an end of the channel, every performative a role
    may send in known languages, contents that are terms of them, sound size estimates."""
    where = f"{ch.name} {cp.protocol}"
    roles = spec.protocols.get(cp.protocol)
    if roles is None:
        return [f"{where}: protocol {cp.protocol!r} is not declared in [protocols]"]
    problems = []
    if cp.initiator not in ch.ends:
        problems.append(f"{where}: the initiator {cp.initiator} is not an end of {ch.name}")
    allowed = set(roles.initiator) | set(roles.participant)
    problems += _language_problems(where, cp, allowed, languages)
    problems += _content_problems(where, cp, allowed, languages)
    return problems + _size_problems(where, cp, allowed)


def _language_problems(
    where: str, cp: ChannelProtocol, allowed: set[str], languages: Mapping[str, Language]
) -> list[str]:
    """Each performative a role may send has a language (not-understood and cancel excepted);
    each language given exists and is for a performative a role may send."""
    problems = []
    for perf, langs in cp.languages.items():
        if perf not in allowed:
            problems.append(f"{where}: a language is given for {perf}, which neither role may send")
        for lang in (langs,) if isinstance(langs, str) else langs:
            if lang not in languages:
                problems.append(f"{where}: {perf} in unknown language {lang!r}")
    return problems + [
        f"{where}: {perf} may be sent but has no language"
        for perf in sorted(allowed - _NO_LANGUAGE - set(cp.languages))
    ]


def _content_problems(
    where: str, cp: ChannelProtocol, allowed: set[str], languages: Mapping[str, Language]
) -> list[str]:
    """The contents named for a performative are terms of its languages."""
    problems = []
    for perf, names in cp.contents.items():
        given: str | tuple[str, ...] | None = cp.languages.get(perf)
        if perf not in allowed or given is None:
            problems.append(f"{where}: contents are given for {perf}, which has no language here")
            continue
        in_langs = (given,) if isinstance(given, str) else given
        terms = {t.__name__ for lang in in_langs if lang in languages for t in languages[lang].types}
        problems += [
            f"{where}: {perf} may carry {name}, which is no term of {'/'.join(in_langs)}"
            for name in names
            if name not in terms
        ]
    return problems


def _size_problems(where: str, cp: ChannelProtocol, allowed: set[str]) -> list[str]:
    """Size estimates are for performatives a role may send, and sound intervals."""
    problems = []
    for perf, (low, high) in cp.sizes.items():
        if perf not in allowed and perf != "not-understood":
            problems.append(f"{where}: a size estimate is given for {perf}, which neither role may send")
        if not 0 < low <= high:
            problems.append(
                f"{where}: the size estimate of {perf} must be 0 < min ≤ max, not [{low}, {high}]"
            )
    return problems


def _end_problems(spec: SystemSpec) -> list[str]:
    """Every agent ends a channel and both sends and receives; every external role ends one."""
    problems = []
    for a in spec.agents:
        if not any(a.name in ch.ends for ch in spec.channels):
            problems.append(f"agent {a.name} ends no channel")
        iface = interface(spec, a.name)
        if not iface.sends or not iface.receives:
            problems.append(f"agent {a.name} can only {'receive' if iface.receives else 'send'}")
    for e in spec.externals:
        if not any(e.name in ch.ends for ch in spec.channels):
            problems.append(f"external role {e.name} ends no channel")
    return problems


def check_report(path: Path = DEFAULT_SPEC) -> tuple[bool, str]:
    """``roco spec check``: (ok, the report's text). A file that does not load is one problem."""
    try:
        spec = load(path)
        d = load_decomposition(path)
    except SpecError as exc:
        return False, f"{exc}"
    problems = check_decomposition(d, spec) + check_interfaces(spec)
    externals = f", {len(spec.externals)} external role(s)" if spec.externals else ""
    head = (
        f"{path}: {len(d.requirements)} requirements, {len(d.steps)} steps, "
        f"{len(spec.agents)} agents{externals}, {len(spec.channels)} channels"
    )
    if not problems:
        return True, f"{head}\nOK: the decomposition is sound and the interfaces match the channels"
    return False, "\n".join([head, *(f"- {p}" for p in problems), f"{len(problems)} problem(s)"])
