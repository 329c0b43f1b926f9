"""``roco spec new-agent NAME``: the folder of an agent a decomposition step introduced, written
from the specification (paper §4 step 4: an agent's interface follows from its channels;
docs/spec.md, "Walk-through: adding an agent").

The agent's ``[[agents]]`` entry names its implementation (``services.agents.watch.agent:WorldWatch``):
the command writes that module, with ``__init__.py`` in every folder on the way, under a root
folder (the project by default). The module holds

- the agent class with its ``ROLES``: one per (channel, protocol) the specification gives it,
  initiator or participant, with the channel's content languages
  (:func:`services.runtime.roles.spec_roles`), each named by services/spec/names.py
  (``initiator(C9, FIPA_QUERY, L_WM)``; ``roco spec new-agent`` renders that module again
  first, services/spec/render_names.py);
- one handler per performative the other role may send by the protocol's state machine
  (what :func:`services.runtime.roles.role_problems` requires; ``@handles(FIPA_QUERY,
  INITIATOR, Performative.INFORM_REF)``), each raising
  NotImplementedError with a line saying what to decide, until written; ``roco spec
  verify-code`` lists the handlers not yet written. Above each, comments name what the
  received communicate carries and every way the role may answer in the state it leads to, as
  calls of the roles' API (``conv.reply``, ``conv.refuse_with``, ``conv.cancel``; derived
  from the protocol's state machine and the channel's contents);
- an FSM of one behaviour that routes the input buffer to the handlers; for an agent that
  initiates a protocol, a periodic behaviour (services/runtime/behaviour.py ``periodic``) whose
  ``_periodically`` runs every ``OPEN_EVERY_S`` seconds, with the ``self.roles.open(...)`` of
  each conversation it may open written there as a comment.

It refuses to overwrite an existing file (FileExistsError).
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from services.runtime.roles import RoleDecl, incoming, optional, spec_roles
from services.spec.model import ChannelProtocol, SpecError, SystemSpec
from services.spec.protocol_defs import machine_of
from services.spec.render_names import python_name
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.languages import load_all
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Protocol, Role

PROJECT = Path(__file__).resolve().parents[2]
"""The project's root folder (where ``services/`` is)."""

OPEN_EVERY_S = 5.0
"""The period (s) a written initiator opens its conversations with, until the user changes it."""

TIMER_METHOD = "_periodically"
"""The method of a written agent that its periodic behaviour runs every ``OPEN_EVERY_S`` s."""

WIDTH = 100
"""Longest line of a comment the stub holds (ruff's limit is 110)."""

_REASONS = frozenset({Performative.REFUSE, Performative.FAILURE})
"""Answers that carry a reason a person can read: ``conv.refuse_with(performative, reason)``."""


@dataclass(frozen=True)
class Scaffold:
    """What :func:`write_agent` wrote: the module's path, the handlers to fill in, and the
    method its periodic behaviour runs (None when the agent initiates nothing)."""

    module: Path
    handlers: tuple[str, ...]
    timer: str | None = None


@dataclass
class _Handler:
    """One handler of a written agent: ``performative`` received in role ``decl``."""

    decl: RoleDecl
    performative: Performative
    on_channel: bool
    """The handler is for ``decl.channel`` only (the agent plays the role on several channels)."""
    level: int = 0
    """How much its method name says: performative, + channel, + protocol, + role."""

    def parts(self) -> list[str]:
        parts = []
        if self.on_channel:
            parts.append(self.decl.channel.lower())
        if self.level >= 1:
            parts.append(self.decl.protocol)
        if self.level >= 2:
            parts.append(self.decl.role)
        return [*parts, self.performative.value]

    @property
    def name(self) -> str:
        return "_on_" + "_".join(p.replace("-", "_") for p in self.parts())


def _peer(spec: SystemSpec, agent: str, channel: str) -> str:
    for ch in spec.channels:
        if ch.name == channel:
            return ch.ends[1] if ch.ends[0] == agent else ch.ends[0]
    raise SpecError(f"no channel {channel}")


def _channel_protocol(spec: SystemSpec, channel: str, protocol: str) -> ChannelProtocol:
    for ch in spec.channels:
        if ch.name == channel:
            for cp in ch.protocols:
                if cp.protocol == protocol:
                    return cp
    raise SpecError(f"channel {channel} carries no {protocol}")


def _channel(decl: RoleDecl) -> str:
    """The name of ``decl``'s channel in services/spec/names.py (``C9``)."""
    return python_name("channel", decl.channel)


def _protocol(decl: RoleDecl) -> str:
    """The name of ``decl``'s protocol in services/spec/names.py (``FIPA_QUERY``)."""
    return python_name("protocol", decl.protocol)


def _languages(decl: RoleDecl) -> list[str]:
    """The names of ``decl``'s languages in services/spec/names.py (``L_WM``)."""
    return [python_name("language", lang) for lang in decl.languages]


def _import(module: str, names: Iterable[str]) -> str:
    """``from module import names`` as ruff's isort writes it: the names in natural order (``C2``
    before ``C10``), on one line when it fits in 110 characters, else one name a line."""
    ordered = sorted(names, key=lambda n: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", n)])
    line = f"from {module} import {', '.join(ordered)}"
    if len(line) <= 110:
        return line
    return f"from {module} import (\n" + "".join(f"    {n},\n" for n in ordered) + ")"


def _literal(text: str) -> str:
    """``text`` as a double-quoted Python string literal."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _constant(name: str) -> str:
    return name.upper().replace("-", "_")


def _term_modules() -> dict[str, str]:
    """Content term name → the module that defines it (shared/fipa_codec/languages)."""
    return {t.__name__: t.__module__ for lang in load_all().values() for t in lang.types}


def _carries(cp: ChannelProtocol, perf: Performative, modules: dict[str, str]) -> str:
    """What ``perf`` carries on its channel: its content terms and their module, or its language."""
    terms = cp.content_types(perf.value)
    if terms:
        where = sorted({modules[t] for t in terms if t in modules})
        return " or ".join(terms) + (f" ({', '.join(where)})" if where else "")
    if perf in _REASONS:
        return "a reason (text: conv.reason)"
    language = cp.languages.get(perf.value)
    if language is None:
        return "no content"
    names = (language,) if isinstance(language, str) else language
    return f"a term of {' or '.join(names)}, or none"


def _call(perf: Performative, cp: ChannelProtocol, role: Role) -> str:
    """The roles' call that sends ``perf`` in a conversation (services/runtime/roles/
    :class:`~services.runtime.roles.Conversation`)."""
    terms = cp.content_types(perf.value)
    term = f"{terms[0]}(…)" if len(terms) == 1 else "content" if terms else ""
    if perf is Performative.CANCEL and role == INITIATOR:
        return f"conv.cancel({term})"
    if perf in _REASONS:
        return f"conv.refuse_with(Performative.{_constant(perf.value)}, reason)"
    return f"conv.reply(Performative.{_constant(perf.value)}{', ' + term if term else ''})"


def _sends(machine: Protocol, role: Role, state: str) -> list[Performative]:
    """What ``role`` may send in ``state`` (not-understood left out): answers with content
    first, then cancel, then refuse and failure."""
    found = {p for (r, p, _) in machine.allowed(state) if r == role and p is not Performative.NOT_UNDERSTOOD}
    return sorted(found, key=lambda p: (p in _REASONS, p is Performative.CANCEL, p.value))


def _by_kind(p: Performative) -> tuple[bool, bool, str]:
    """Answers with content first, then cancel, then refuse and failure."""
    return (p in _REASONS, p is Performative.CANCEL, p.value)


def _sends_in(machine: Protocol, role: Role, states: Iterable[str]) -> list[Performative]:
    """What ``role`` may send in any of ``states``, each once, in the states' order."""
    sends: list[Performative] = []
    for t in states:
        sends += [p for p in _sends(machine, role, t) if p not in sends]
    return sends


def _failure_note(perf: Performative, role: Role) -> list[str]:
    """An initiator's failure handler is reached for more than failure."""
    if perf is Performative.FAILURE and role == INITIATOR:
        return [
            "Also reached when the reply-by deadline passed (conv.timed_out), the peer did not "
            "understand (conv.not_understood), or this agent could not read the answer "
            "(conv.unreadable); conv.reason says why."
        ]
    return []


def _agree_line(machine: Protocol, cp: ChannelProtocol, role: Role, targets: list[str]) -> list[str]:
    """What the role may send later, after it agreed (agree now, the outcome later: FIPA
    SC00026 §2)."""
    afters = [machine.next_state(t, role, Performative.AGREE) for t in targets]
    later = _sends_in(machine, role, [a for a in afters if a is not None and a not in machine.final])
    if not later:
        return []
    follow = "; or ".join(_call(q, cp, role) for q in later)
    return [f"After {_call(Performative.AGREE, cp, role)}, later (keep conv): {follow}."]


def _unique(out: list[_Handler]) -> list[_Handler]:
    """``out`` with the names of handlers that clash made longer (their ``level`` raised) until
    none clash."""
    while True:
        names: dict[str, list[_Handler]] = {}
        for h in out:
            names.setdefault(h.name, []).append(h)
        clashes = [h for same in names.values() if len(same) > 1 for h in same]
        if not clashes:
            return out
        for h in clashes:
            h.level += 1
        assert all(h.level <= 2 for h in out), "a handler key is unique at level 2"


def _handler_block(
    spec: SystemSpec, agent: str, h: _Handler, todo_where: tuple[str, str], modules: dict[str, str]
) -> str:
    """One handler's method: its decorator, docstring, hints, and the NotImplementedError
    that says where to write it (``todo_where``: the class name and the module's path)."""
    class_name, where = todo_where
    decl, perf = h.decl, h.performative
    peer = _peer(spec, agent, decl.channel)
    what = f"{agent}: {perf.value} from {peer} on {decl.channel} ({decl.protocol}) is not handled yet: "
    todo = _literal(what) + "\n            " + _literal(f"write {class_name}.{h.name} in {where}")
    channel = f", channel={_channel(decl)}" if h.on_channel else ""
    return (
        f"    @handles({_protocol(decl)}, {_constant(decl.role)}, Performative.{perf.name}{channel})\n"
        f"    def {h.name}(self, conv: Conversation) -> None:\n"
        f'        """{peer} sent {perf.value} ({decl.protocol} on {decl.channel}, this agent the '
        f'{decl.role})."""\n'
        + _comment(_hints(spec, h, modules), "        ")
        + f"        raise NotImplementedError(\n            {todo}\n        )\n"
    )


_SERVE_ONLY = """                Behaviour(
                    "serve", self.handle_received, terminal=lambda: False, doc="answer what arrives"
                )"""
"""The behaviour of an agent that only answers."""

_SERVE_AND_OPEN = """                periodic(
                    "serve",
                    OPEN_EVERY_S,
                    self.{timer},
                    serve=self.handle_received,
                    doc=f"answer what arrives; every {{OPEN_EVERY_S:g}} s open conversations",
                )"""
"""The behaviour of an agent that also opens conversations (``{timer}``: :data:`TIMER_METHOD`)."""


def _behaviour(
    spec: SystemSpec, agent: str, opens: list[RoleDecl], modules: dict[str, str]
) -> tuple[str, ...]:
    """What the module imports from services/runtime/agent.py, the period's constant, the
    behaviour, and the timer method that opens conversations (empty for an agent that only
    answers)."""
    if not opens:
        return "FSM, Agent, Behaviour", "", _SERVE_ONLY, ""
    period = f"""
OPEN_EVERY_S = {OPEN_EVERY_S!r}
\"\"\"How often (s) {TIMER_METHOD} runs: the period of this agent's periodic behaviour.\"\"\"
"""
    timer = (
        f"    def {TIMER_METHOD}(self) -> None:\n"
        f'        """Runs every OPEN_EVERY_S s (services/runtime/behaviour.py ``periodic``): open the\n'
        f'        conversations this agent initiates; the answers reach the handlers below."""\n'
        + "".join(_opening(spec, d, _peer(spec, agent, d.channel), modules) for d in opens)
        + "\n"
    )
    return "FSM, Agent, periodic", period, _SERVE_AND_OPEN.format(timer=TIMER_METHOD), timer


def _module_of(spec: SystemSpec, agent: str) -> tuple[list[str], str]:
    """Agent ``agent``'s module path (its dotted parts) and class name; SpecError for an agent
    the specification does not name or an implementation that is not ``package.module:Class``."""
    entry = next((a for a in spec.agents if a.name == agent), None)
    if entry is None:
        names = ", ".join(a.name for a in spec.agents)
        raise SpecError(f"the specification has no agent {agent!r} (it has {names})")
    module, _, class_name = entry.implementation.partition(":")
    parts = module.split(".")
    if not class_name.isidentifier() or len(parts) < 2 or not all(p.isidentifier() for p in parts):
        raise SpecError(f"agent {agent}: implementation {entry.implementation!r} is not package.module:Class")
    return parts, class_name


def _packages(root: Path, parts: list[str]) -> None:
    """The folders of package path ``parts`` under ``root``, each with an ``__init__.py``."""
    folder = root
    for part in parts:
        folder = folder / part
        folder.mkdir(exist_ok=True)
        init = folder / "__init__.py"
        if not init.exists():
            init.write_text("")


def _answer_line(
    machine: Protocol, cp: ChannelProtocol, role: Role, sends: list[Performative], targets: list[str]
) -> str:
    """The calls that answer (a participant) or may follow (an initiator), and whether the
    communicate may have ended the conversation instead."""
    calls = "; or ".join(_call(p, cp, role) for p in sends)
    ends = any(t in machine.final for t in targets)
    return (
        ("Answer with " if role == PARTICIPANT else "May send: ")
        + calls
        + (", unless it ended the conversation" if ends else "")
        + "."
    )


def _hints(spec: SystemSpec, h: _Handler, modules: dict[str, str]) -> list[str]:
    """The comment lines above a handler: what arrived, and what the role may send in the
    states it leads to by the protocol's state machine (each as the roles' call)."""
    decl, perf = h.decl, h.performative
    cp = _channel_protocol(spec, decl.channel, decl.protocol)
    machine = machine_of(spec, decl.protocol)
    other: Role = PARTICIPANT if decl.role == INITIATOR else INITIATOR
    lines = [f"conv.content: {_carries(cp, perf, modules)}.", *_failure_note(perf, decl.role)]
    edges = [*machine.transitions.items(), *machine.terminal_transitions.items()]
    targets = sorted({t for (_, r, p), t in edges if r == other and p is perf})
    sends = sorted(_sends_in(machine, decl.role, targets), key=_by_kind)
    if not sends:
        lines.append("It ends the conversation: nothing more is sent in it.")
        return lines
    lines.append(_answer_line(machine, cp, decl.role, sends, targets))
    if Performative.AGREE in sends:
        lines += _agree_line(machine, cp, decl.role, targets)
    return lines


def _comment(lines: list[str], indent: str) -> str:
    """``lines`` as comment lines of at most :data:`WIDTH` characters."""
    out: list[str] = []
    for line in lines:
        out += textwrap.wrap(
            line, WIDTH - len(indent) - 2, break_long_words=False, break_on_hyphens=False
        ) or [""]
    return "".join(f"{indent}# {line}\n" for line in out)


def _summary(agent: str, job: str) -> str:
    """The module docstring's opening, ``agent — job.``, in lines of at most :data:`WIDTH`
    characters; a backslash and a run of three quotes in ``job`` escaped, so that the docstring
    reads as the job was written and stays one string."""
    said = " ".join(job.split()).rstrip(".").replace("\\", "\\\\").replace('"""', '\\"\\"\\"')
    lines = textwrap.wrap(f"{agent} — {said}.", WIDTH, break_long_words=False, break_on_hyphens=False)
    return "\n".join(lines)


def _roles_tuple(declared: list[str]) -> str:
    """The class's ``ROLES = (…)`` from its entries, as ruff formats it: one role on one line
    when it fits, else one per line."""
    if len(declared) == 1 and len(one := f"    ROLES = ({declared[0].strip()})") <= WIDTH:
        return one
    return "    ROLES = (\n" + "\n".join(declared) + "\n    )"


def _handlers(spec: SystemSpec, roles: list[RoleDecl]) -> list[_Handler]:
    """One handler per performative each role must handle, named uniquely: by performative,
    with the channel when the agent plays the role on several channels, and with the protocol
    (then the role) while two names would still be the same."""
    counts: dict[tuple[str, str, Performative], int] = {}
    needed: list[tuple[RoleDecl, Performative]] = []
    for decl in roles:
        machine = machine_of(spec, decl.protocol)
        for p in sorted(incoming(machine, decl.role) - optional(machine, decl.role), key=lambda p: p.value):
            needed.append((decl, p))
            key = (decl.role, decl.protocol, p)
            counts[key] = counts.get(key, 0) + 1
    return _unique([_Handler(d, p, counts[(d.role, d.protocol, p)] > 1) for d, p in needed])


def _opening(spec: SystemSpec, decl: RoleDecl, peer: str, modules: dict[str, str]) -> str:
    """The commented ``self.roles.open(...)`` of an initiator role, with what it carries."""
    machine = machine_of(spec, decl.protocol)
    cp = _channel_protocol(spec, decl.channel, decl.protocol)
    openers = sorted(
        (p for (s, r, p) in machine.transitions if s == machine.initial and r == INITIATOR),
        key=lambda p: p.value,
    )
    carried: dict[str, list[str]] = {}
    for p in openers:
        carried.setdefault(_carries(cp, p, modules), []).append(p.value)
    said = "; ".join(f"{' or '.join(perfs)} carries {what}" for what, perfs in carried.items())
    text = [f"{decl.channel} {decl.protocol} with {peer}: {said}."]
    shown = next((p for p in openers if cp.content_types(p.value)), openers[0])
    terms = cp.content_types(shown.value)
    content = f"{terms[0]}(…)" if len(terms) == 1 else "content"
    call = f"self.roles.open({_channel(decl)}, {_protocol(decl)}, {content}"
    if len(openers) > 1:
        call += f", performative=Performative.{_constant(shown.value)}"
    return _comment(text, "        ") + f"        # {call})\n"


def _declared(roles: list[RoleDecl]) -> tuple[list[str], set[str]]:
    """The lines of the class's ``ROLES``, and the names of services.spec.names they use."""
    declared = []
    named: set[str] = set()
    for decl in roles:
        names = [_channel(decl), _protocol(decl), *_languages(decl)]
        named |= set(names)
        declared.append(f"        {decl.role}({', '.join(names)}),")
    return declared, named


def _role_imports(roles: list[RoleDecl]) -> str:
    """What the module imports from services.runtime.roles."""
    role_names = sorted({_constant(d.role) for d in roles})
    makers = sorted({d.role for d in roles})
    return ", ".join([*role_names, "Conversation", "handles", *makers])


def _imports_block(lines: dict[str, str]) -> str:
    """The module's imports (module → its import statement) in the order isort gives them: by
    module name (the system's names module among roco's)."""
    return "\n".join(lines[module] for module in sorted(lines))


def agent_source(spec: SystemSpec, agent: str, class_name: str, where: str) -> tuple[str, tuple[str, ...]]:
    """The module text of agent ``agent`` (class ``class_name``, written to ``where``) and
    the names of its handlers. Raises SpecError when the spec gives the agent no channel."""
    entry = next(a for a in spec.agents if a.name == agent)
    roles = spec_roles(spec, agent)
    if not roles:
        raise SpecError(f"agent {agent} ends no channel in the specification: it would have nothing to do")
    modules = _term_modules()
    declared, named = _declared(roles)
    handlers = _handlers(spec, roles)
    blocks = [_handler_block(spec, agent, h, (class_name, where), modules) for h in handlers]
    opens = [d for d in roles if d.role == INITIATOR]
    imports = _role_imports(roles)
    job = entry.job or f"the agent that substitutes group {entry.group}"
    unused = "" if handlers else "  # noqa: F401  (the performatives handlers answer with)"
    behaviour_import, period, serve, timer = _behaviour(spec, agent, opens, modules)
    imports_block = _imports_block(
        {
            "services.runtime.agent": f"from services.runtime.agent import {behaviour_import}",
            "services.runtime.roles": f"from services.runtime.roles import {imports}",
            spec.names_module: _import(spec.names_module, named),
            "shared.fipa_codec": f"from shared.fipa_codec import Performative{unused}",
        }
    )
    text = f'''"""{_summary(agent, job)}

Written by ``roco spec new-agent {agent}`` from the specification: its protocol roles (one per
channel and protocol the specification gives it) and one handler per performative its peers
may send. Each handler raises NotImplementedError until it is written; ``roco spec
verify-code`` lists those not yet written. The runtime's roles answer not-understood, cancels
without a handler, and passed reply-by deadlines (services/runtime/roles/).
"""

from __future__ import annotations

{imports_block}
{period}

class {class_name}(Agent):
    name = "{agent}"
{_roles_tuple(declared)}

    def build_fsm(self) -> FSM:
        return FSM(
            [
{serve}
            ]
        )

{timer}{chr(10).join(blocks)}'''
    return text.rstrip() + "\n", tuple(h.name for h in handlers)


def write_agent(spec: SystemSpec, agent: str, root: Path = PROJECT) -> Scaffold:
    """Write agent ``agent``'s module (see the module docstring) under ``root``. Raises
    SpecError for an agent the specification does not name or an implementation that is not
    ``package.module:Class``, FileExistsError when the module exists."""
    parts, class_name = _module_of(spec, agent)
    path = root.joinpath(*parts).with_suffix(".py")
    if path.exists():
        raise FileExistsError(f"{path} exists; new-agent writes only new files")
    shown = path.relative_to(root) if path.is_relative_to(root) else path
    text, handlers = agent_source(spec, agent, class_name, str(shown))
    _packages(root, parts[:-1])
    path.write_text(text)
    timer = TIMER_METHOD if any(d.role == INITIATOR for d in spec_roles(spec, agent)) else None
    return Scaffold(path, handlers, timer)
