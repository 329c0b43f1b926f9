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
never by an agent.

Interface rules (paper §4 steps 3–4): every channel protocol exists and is initiated by one of
the channel's ends; every performative a role may send has a language (not-understood and
cancel excepted), every language exists; the content schemas named for a performative are
terms of its language and the size estimates are sound intervals; every agent ends at
least one channel.
"""

from __future__ import annotations

from pathlib import Path

from services.spec.decomposition import Decomposition, load_decomposition
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, interface, load

_NO_LANGUAGE = frozenset({"not-understood", "cancel"})


def check_decomposition(d: Decomposition, spec: SystemSpec | None = None) -> list[str]:
    """Every violation of the decomposition rules (see module docstring), as sentences."""
    problems: list[str] = []
    ids = [r.id for r in d.requirements]
    known = set(ids)
    for i in sorted({x for x in ids if ids.count(x) > 1}):
        problems.append(f"requirement {i} is defined more than once")
    roots = [r.id for r in d.requirements if r.parent is None]
    if len(roots) != 1:
        problems.append(f"the requirement tree needs exactly one root, not {len(roots)} ({', '.join(roots)})")
    parent = {r.id: r.parent for r in d.requirements}
    for req in d.requirements:
        if req.parent is not None and req.parent not in known:
            problems.append(f"requirement {req.id}: its parent {req.parent} does not exist")
        seen: set[str] = set()
        node: str | None = req.id
        while node is not None and node in parent and node not in seen:
            seen.add(node)
            node = parent[node]
        if node is not None and node in seen:
            problems.append(f"requirement {req.id} is its own ancestor")
    if not d.steps:
        problems.append("no decomposition steps")
        return problems

    fringe = [d.system]
    outside: list[str] = []
    used = {d.system}
    channels: dict[int, tuple[str, str]] = {}
    addressed: dict[str, int] = {}
    for n, step in enumerate(d.steps, 1):
        where = f"step {step.number}"
        if step.number != n:
            problems.append(f"{where}: steps must be numbered 1, 2, 3, ...; expected {n}")
        for rid in step.requirements:
            if rid not in known:
                problems.append(f"{where}: addresses unknown requirement {rid}")
            addressed.setdefault(rid, step.number)
        if step.split is not None or step.into is not None:
            if step.split is None or step.into is None:
                problems.append(f"{where}: a split needs both 'split' and 'into'")
            elif step.split not in fringe:
                problems.append(
                    f"{where}: splits group {step.split!r}, which is not in the fringe ({', '.join(fringe)})"
                )
            else:
                a, b = step.into
                if a == b or a in used or b in used:
                    problems.append(
                        f"{where}: {step.split} must split into two new groups, not {a!r} and {b!r}"
                    )
                if set(step.tasks) != {a, b}:
                    problems.append(f"{where}: give the tasks of exactly {a} and {b}")
                reallocated = {r.number for r in step.reallocated}
                for k, ends in sorted(channels.items()):
                    if step.split in ends and k not in reallocated:
                        problems.append(
                            f"{where}: channel C{k} ends at {step.split!r}, which this step splits "
                            f"into {a} and {b}; reallocate it to one of them"
                        )
                for r in step.reallocated:
                    current = channels.get(r.number)
                    if current is None:
                        problems.append(f"{where}: reallocates C{r.number}, which does not exist yet")
                    elif r.from_ != step.split or r.from_ not in current:
                        problems.append(
                            f"{where}: C{r.number} can only move from the split group {step.split!r} "
                            f"(its ends are {current[0]} and {current[1]})"
                        )
                    elif r.to not in step.into:
                        problems.append(f"{where}: C{r.number} must move to {a} or {b}, not {r.to!r}")
                pos = fringe.index(step.split)
                fringe = [*fringe[:pos], a, b, *fringe[pos + 1 :]]
                used |= {a, b}
        elif not step.new_channels and not step.supplemented:
            problems.append(f"{where}: neither splits a group nor creates or supplements a channel")
        for group in step.outside:
            if group in used:
                problems.append(f"{where}: the group outside the system {group!r} must be a new group")
            outside.append(group)
            used.add(group)
        for r in step.reallocated:
            if r.number in channels and r.from_ in channels[r.number]:
                old = channels[r.number]
                channels[r.number] = (r.to, old[1]) if old[0] == r.from_ else (old[0], r.to)
        for c in step.new_channels:
            expected = max(channels, default=0) + 1
            if c.number != expected:
                problems.append(f"{where}: new channel C{c.number} should be numbered C{expected}")
            if all(end in outside for end in c.ends):
                problems.append(f"{where}: new channel C{c.number} joins two groups outside the system")
            for end in c.ends:
                if end not in fringe and end not in outside:
                    problems.append(
                        f"{where}: new channel C{c.number} ends at {end!r}, which is not in the fringe "
                        f"({', '.join(fringe)})"
                    )
            if c.ends[0] == c.ends[1]:
                problems.append(f"{where}: new channel C{c.number} joins {c.ends[0]} to itself")
            channels[c.number] = c.ends
        for sup in step.supplemented:
            if sup.number not in channels:
                problems.append(f"{where}: supplements C{sup.number}, which does not exist")
    for rid in ids:
        if rid not in addressed:
            problems.append(f"stop condition: requirement {rid} is addressed by no step")
    for k, ends in sorted(channels.items()):
        for end in ends:
            if end not in fringe and end not in outside:
                problems.append(
                    f"channel C{k} ends at group {end!r}, which no longer exists "
                    f"(fringe: {', '.join(fringe)})"
                )
    if spec is not None:
        problems += _final_matches_spec(fringe, channels, spec, outside)
    return problems


def _final_matches_spec(
    fringe: list[str], channels: dict[int, tuple[str, str]], spec: SystemSpec, outside: list[str]
) -> list[str]:
    problems = []
    agent_of = {a.group: a.name for a in spec.agents}
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
    for g in fringe:
        if g not in agent_of:
            problems.append(f"stop condition: group {g!r} of the final fringe is substituted by no agent")
    for a in spec.agents:
        if a.group not in fringe:
            problems.append(f"agent {a.name} substitutes group {a.group!r}, which is not in the final fringe")
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
    for c in spec.channels:
        if c.name not in {f"C{k}" for k in channels}:
            problems.append(f"channel {c.name} in [[channels]] was created by no decomposition step")
    return problems


def check_interfaces(spec: SystemSpec) -> list[str]:
    """Every violation of the interface rules (see module docstring), as sentences."""
    from shared.fipa_codec.languages import load_all
    from shared.fipa_codec.protocols import PROTOCOLS

    LANGUAGES = load_all()
    problems = []
    for ch in spec.channels:
        for cp in ch.protocols:
            where = f"{ch.name} {cp.protocol}"
            roles = spec.protocols.get(cp.protocol)
            if roles is None:
                problems.append(f"{where}: protocol {cp.protocol!r} is not declared in [protocols]")
                continue
            if cp.protocol not in PROTOCOLS:
                problems.append(f"{where}: no state machine for protocol {cp.protocol!r}")
            if cp.initiator not in ch.ends:
                problems.append(f"{where}: the initiator {cp.initiator} is not an end of {ch.name}")
            allowed = set(roles.initiator) | set(roles.participant)
            for perf, langs in cp.languages.items():
                if perf not in allowed:
                    problems.append(f"{where}: a language is given for {perf}, which neither role may send")
                for lang in (langs,) if isinstance(langs, str) else langs:
                    if lang not in LANGUAGES:
                        problems.append(f"{where}: {perf} in unknown language {lang!r}")
            for perf in sorted(allowed - _NO_LANGUAGE - set(cp.languages)):
                problems.append(f"{where}: {perf} may be sent but has no language")
            for perf, names in cp.contents.items():
                given: str | tuple[str, ...] | None = cp.languages.get(perf)
                if perf not in allowed or given is None:
                    problems.append(f"{where}: contents are given for {perf}, which has no language here")
                    continue
                in_langs = (given,) if isinstance(given, str) else given
                terms = {t.__name__ for lang in in_langs if lang in LANGUAGES for t in LANGUAGES[lang].types}
                for name in names:
                    if name not in terms:
                        problems.append(
                            f"{where}: {perf} may carry {name}, which is no term of {'/'.join(in_langs)}"
                        )
            for perf, (low, high) in cp.sizes.items():
                if perf not in allowed and perf != "not-understood":
                    problems.append(
                        f"{where}: a size estimate is given for {perf}, which neither role may send"
                    )
                if not 0 < low <= high:
                    problems.append(
                        f"{where}: the size estimate of {perf} must be 0 < min ≤ max, not [{low}, {high}]"
                    )
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
