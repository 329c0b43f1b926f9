"""``roco spec verify-code``: every message an agent may receive by the specification has a
handler in that agent's code, and every message its code sends is allowed by the
specification (the paper's ClassInterfaceInfo check, §5.6).

An agent's code is the package of its ``implementation`` (``services.agents.planner.agent:Planner``
→ every module of ``services/agents/planner/``).

Every agent declares its protocol roles (``ROLES``; services/runtime/roles/) and is checked
exactly, by the comparison it also runs when it starts
(:func:`services.runtime.roles.agent_problems`): its roles against its interface in the
specification — every channel, protocol, role and content language, none missing, none
extra; a role declared for every channel counts once per channel it stands for
(:func:`services.runtime.roles.expand_roles`) —, a handler for every performative the other
role may send by the protocol's state machine and none for anything else, and its whole
folder read for sends outside its roles (services/runtime/code_scan.py). The report lists, per
role, what it sends and receives.

An agent that declares no roles (``ROLES`` None) is one problem: nothing but its roles may
send, so there is nothing else to read.

What it proves: each agent plays exactly the roles the specification gives it, in the
channel's languages; it has a handler for everything its peers may send by the protocols'
state machines and none for anything else; and its code sends only through its roles
(which check every communicate against the state machine when it is sent). What it does
not prove: that a handler decides well, that a conversation the agent should open is ever
opened, or anything about a performative built from a string at run time
(services/runtime/code_scan.py says what the reading cannot see). ``roco spec verify RUN``
checks what a run actually sent.
"""

from __future__ import annotations

import ast
import importlib.util
import inspect
from functools import cache
from pathlib import Path

from services.runtime.agent import OVERRIDABLE, Agent
from services.runtime.main import agent_class
from services.runtime.roles import (
    EVERY_CHANNEL,
    RoleDecl,
    agent_problems,
    expand_roles,
    incoming,
    outgoing,
    spec_roles,
)
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, load
from services.spec.protocol_defs import machine_of
from shared.fipa_codec.acts import Performative


def package_files(implementation: str) -> list[Path]:
    """The source files of the package that holds ``module:Class``. Raises SpecError when the
    module cannot be found."""
    module = implementation.split(":", 1)[0]
    try:
        spec = importlib.util.find_spec(module)
    except ModuleNotFoundError:  # a missing parent package
        spec = None
    if spec is None or spec.origin is None:
        raise SpecError(f"implementation {implementation!r}: no module {module!r}")
    return sorted(Path(spec.origin).parent.glob("*.py"))


def role_lines(
    spec: SystemSpec,
    agent: str,
    roles: list[RoleDecl],
    unused: set[tuple[str, str]],
    every: set[tuple[str, str]] | None = None,
) -> list[str]:
    """Per role: channel, protocol, role, peer, languages, and the performatives it receives
    and sends by the protocol's state machine (not-understood, always allowed, left out);
    ``unused``: the (channel, protocol) of initiator roles the agent opens no conversation in;
    ``every``: those the agent declares by one role for every channel."""
    channels = {ch.name: ch for ch in spec.channels}
    out = []
    for decl in roles:
        if (decl.channel, decl.protocol) in unused:
            out.append(
                f"  {decl.channel} {decl.protocol} {decl.role}: declared unused (opens no conversation)"
            )
            continue
        ends = channels[decl.channel].ends
        peer = ends[1] if ends[0] == agent else ends[0]
        machine = machine_of(spec, decl.protocol)
        nu = {Performative.NOT_UNDERSTOOD}
        receives = sorted(p.value for p in incoming(machine, decl.role) - nu)
        sends = sorted(p.value for p in outgoing(machine, decl.role) - nu)
        how = " (declared for every channel)" if (decl.channel, decl.protocol) in (every or set()) else ""
        out.append(
            f"  {decl.channel} {decl.protocol} {decl.role} with {peer} in {', '.join(decl.languages)}{how}: "
            f"receives {_perfs(receives)}; sends {_perfs(sends)}"
        )
    return out


def _perfs(names: list[str]) -> str:
    """Performatives as a list in words (``nothing`` for none: a one-message protocol's)."""
    return ", ".join(names) or "nothing"


def _agent_lines(spec: SystemSpec, name: str, implementation: str) -> tuple[list[str], list[str]]:
    """One agent's problems, and its lines of the report: its files, its protocol roles and
    whether they agree with the specification, each role's messages."""
    files = package_files(implementation)
    cls = agent_class(spec, name)
    found = shadowing(name, cls) + agent_problems(spec, name, cls, files)
    written = cls.ROLES or ()
    declared = expand_roles(spec, name, written)
    lines = [
        f"{name}: {len(files)} files; {len(declared)} protocol roles"
        f"{' agree with the specification' if not found else ''}:"
    ]
    unused = {(d.channel, d.protocol) for d in declared if d.unused}
    own = {(d.channel, d.protocol) for d in written if d.channel != EVERY_CHANNEL}
    every = {(d.channel, d.protocol) for d in declared} - own
    lines += role_lines(spec, name, spec_roles(spec, name), unused, every)
    return found, lines


def _self_attributes(node: ast.AST) -> set[str]:
    """The names assigned as ``self.<name>`` anywhere under ``node``."""
    found = set()
    for n in ast.walk(node):
        targets = (
            n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, ast.AnnAssign) else []
        )
        for t in targets:
            if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id == "self":
                found.add(t.attr)
    return found


@cache
def runtime_names() -> frozenset[str]:
    """The names an agent inherits from the runtime's :class:`~services.runtime.agent.Agent`:
    its class attributes and methods, and the attributes its methods set on ``self`` (read from
    its source: ``self.roles = …`` in ``__init__``), dunders left out."""
    names = set(dir(Agent))
    tree = ast.parse(Path(inspect.getfile(Agent)).read_text())
    names |= _self_attributes(next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Agent"))
    return frozenset(n for n in names if not (n.startswith("__") and n.endswith("__")))


def shadowing(agent: str, cls: type) -> list[str]:
    """One problem per name of the runtime's :class:`~services.runtime.agent.Agent` that agent
    ``agent``'s class ``cls`` (or a base of its own, not the runtime's) defines again, but those
    it may (``OVERRIDABLE``): an agent's attribute or method that replaces one of the
    runtime's, or is replaced by it, breaks one of them far from the cause (a helper ``post`` the
    person's face calls; an attribute ``roles`` the runtime sets again)."""
    runtime = runtime_names() - OVERRIDABLE
    problems = []
    for klass in cls.__mro__:
        if klass is object or klass.__module__.startswith("services.runtime"):
            continue
        for attr in sorted(runtime & set(vars(klass))):
            where = f"{klass.__name__}.{attr}"
            problems.append(f"agent {agent}: {where} replaces the runtime's Agent.{attr}: name it otherwise")
    return problems


def verify_code_report(path: Path = DEFAULT_SPEC) -> tuple[bool, str]:
    """``roco spec verify-code``: (ok, the report's text). An agent whose code cannot be read
    (no such module, a syntax error) is one problem of the report. Raises SpecError when the
    specification file ``path`` does not load."""
    spec = load(path)
    problems: list[str] = []
    lines: list[str] = []
    for a in spec.agents:
        try:
            found, agent_lines = _agent_lines(spec, a.name, a.implementation)
        except (SpecError, SyntaxError) as exc:
            found, agent_lines = [f"agent {a.name}: {exc}"], [f"{a.name}: its code is not read"]
        problems += found
        lines += agent_lines
    if not problems:
        return True, "\n".join(
            [
                *lines,
                "OK: every receivable message has a handler; every send is allowed (not-understood always)",
            ]
        )
    return False, "\n".join([*lines, *(f"- {p}" for p in problems), f"{len(problems)} problem(s)"])
