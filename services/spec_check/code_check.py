"""``roco spec verify-code``: every message an agent may receive by the specification has a
handler in that agent's code, and every message its code sends is allowed by the
specification (the paper's ClassInterfaceInfo check, §5.6).

An agent's code is the package of its ``implementation`` (``services.agents.planner.agent:Planner``
→ every module of ``services/agents/planner/``).

**An agent that declares its protocol roles** (``ROLES``; services/runtime/roles.py) is checked
exactly, by the comparison it also runs when it starts
(:func:`services.runtime.roles.agent_problems`): its roles against its interface in the
specification — every channel, protocol, role and content language, none missing, none
extra —, a handler for every performative the other role may send by the protocol's state
machine and none for anything else, and its whole folder read for sends outside its roles
(services/runtime/code_scan.py). The report lists, per role, what it sends and receives.

**An agent that declares none** is read by the older heuristic below.
In it:

- a **send** is a call ``self.send(to, Performative.X, …)``, ``self.reply(item,
  Performative.X, …)`` or ``self.fail(item, Performative.X, …)``; X must be a performative the
  agent's interface lets it send (to any peer);
- a **handler** for performative X is a comparison naming ``Performative.X`` (``item.performative
  is Performative.X``, ``perf in (Performative.X, …)``) outside such calls. Every performative
  the interface lets the agent receive *as the participant* of a protocol (a request, a
  query, a subscribe, a cancel) needs one; ``not-understood`` is answered and logged by the
  runtime for every agent;
- a **reply handler** is code matching replies to what the agent itself initiated (a use of
  ``in_reply_to``): the performatives the interface lets the agent receive *as the
  initiator* (agree, inform, failure …) need one.

What it cannot see: which peer and protocol a handler is for; the runtime checks those on
every communicate (services/runtime/agent.py).
"""

from __future__ import annotations

import ast
import importlib.util
from dataclasses import dataclass, field
from pathlib import Path

from services.runtime.main import agent_class
from services.runtime.roles import RoleDecl, agent_problems, incoming, outgoing, spec_roles
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, interface, load
from services.spec.protocol_defs import machine_of
from shared.fipa_codec.acts import Performative

SEND_METHODS = frozenset({"send", "reply", "fail"})
RUNTIME_HANDLED = frozenset({"not-understood"})


@dataclass
class AgentCode:
    """What the code of one agent sends and handles (FIPA performative names), with where."""

    agent: str
    files: list[Path]
    sends: dict[str, list[str]] = field(default_factory=dict)  # performative → "file:line"
    handles: dict[str, list[str]] = field(default_factory=dict)
    matches_replies: list[str] = field(default_factory=list)  # "file:line" of in_reply_to uses


def _fipa(name: str) -> str:
    return name.lower().replace("_", "-")


def _performative(node: ast.AST) -> str | None:
    if (
        isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Name)
        and node.value.id == "Performative"
    ):
        return _fipa(node.attr)
    return None


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


def read_code(agent: str, files: list[Path]) -> AgentCode:
    """Collect the sends and handlers in ``files`` (see module docstring)."""
    code = AgentCode(agent, files)
    for path in files:
        tree = ast.parse(path.read_text(), str(path))
        in_sends: set[int] = set()
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in SEND_METHODS
                and len(node.args) >= 2
            ):
                for sub in ast.walk(node.args[1]):  # Performative.X, or a choice of them
                    perf = _performative(sub)
                    if perf is not None:
                        code.sends.setdefault(perf, []).append(f"{path.name}:{node.lineno}")
                        in_sends.add(id(sub))
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr == "in_reply_to":
                code.matches_replies.append(f"{path.name}:{node.lineno}")
            if not isinstance(node, ast.Compare):
                continue
            for operand in (node.left, *node.comparators):
                elements = operand.elts if isinstance(operand, ast.Tuple | ast.Set | ast.List) else [operand]
                for el in elements:
                    perf = _performative(el)
                    if perf is not None and id(el) not in in_sends:
                        code.handles.setdefault(perf, []).append(f"{path.name}:{el.lineno}")
    return code


def verify_agent(spec: SystemSpec, agent: str, files: list[Path]) -> tuple[AgentCode, list[str]]:
    """The agent's code and every mismatch with its specified interface, as sentences."""
    code = read_code(agent, files)
    iface = interface(spec, agent)
    may_send = {k.performative for k in iface.sends}
    problems = []
    for perf, where in sorted(code.sends.items()):
        if perf not in may_send:
            problems.append(
                f"{agent} sends {perf} ({', '.join(where)}) but its interface allows only "
                f"{', '.join(sorted(may_send))}"
            )
    initiates = {
        (ch.name, cp.protocol) for ch in spec.channels for cp in ch.protocols if cp.initiator == agent
    }
    folder = files[0].parent if files else "?"
    for kind in sorted({(k.performative, k.channel, k.protocol, k.sender) for k in iface.receives}):
        perf, channel, protocol, sender = kind
        if perf in RUNTIME_HANDLED:
            continue
        if (channel, protocol) in initiates:
            if not code.matches_replies:
                problems.append(
                    f"{agent} initiates {protocol} on {channel} but no code in {folder} matches the "
                    f"replies (no use of in_reply_to), e.g. {perf} from {sender}"
                )
            continue
        if perf not in code.handles:
            name = perf.upper().replace("-", "_")
            problems.append(
                f"{agent} may receive {perf} from {sender} on {channel} ({protocol}) but no code in "
                f"{folder} handles it (no comparison with Performative.{name})"
            )
    return code, problems


def role_lines(spec: SystemSpec, agent: str, roles: list[RoleDecl]) -> list[str]:
    """Per role: channel, protocol, role, peer, languages, and the performatives it receives
    and sends by the protocol's state machine (not-understood, always allowed, left out)."""
    channels = {ch.name: ch for ch in spec.channels}
    out = []
    for decl in roles:
        ends = channels[decl.channel].ends
        peer = ends[1] if ends[0] == agent else ends[0]
        machine = machine_of(spec, decl.protocol)
        nu = {Performative.NOT_UNDERSTOOD}
        receives = sorted(p.value for p in incoming(machine, decl.role) - nu)
        sends = sorted(p.value for p in outgoing(machine, decl.role) - nu)
        out.append(
            f"  {decl.channel} {decl.protocol} {decl.role} with {peer} in {', '.join(decl.languages)}: "
            f"receives {', '.join(receives)}; sends {', '.join(sends)}"
        )
    return out


def verify_code_report(path: Path = DEFAULT_SPEC) -> tuple[bool, str]:
    """``roco spec verify-code``: (ok, the report's text)."""
    try:
        spec = load(path)
        problems: list[str] = []
        lines: list[str] = []
        for a in spec.agents:
            files = package_files(a.implementation)
            cls = agent_class(spec, a.name)
            if cls.ROLES is not None:
                found = agent_problems(spec, a.name, cls, files)
                problems += found
                lines.append(
                    f"{a.name}: {len(files)} files; {len(cls.ROLES)} protocol roles"
                    f"{' agree with the specification' if not found else ''}:"
                )
                lines += role_lines(spec, a.name, spec_roles(spec, a.name))
                continue
            code, found = verify_agent(spec, a.name, files)
            problems += found
            sends = ", ".join(sorted(code.sends)) or "nothing"
            handled = ", ".join(sorted(code.handles)) or "nothing"
            lines.append(
                f"{a.name}: {len(files)} files, no protocol roles declared (heuristic scan); "
                f"sends {sends}; handles {handled}"
            )
    except (SpecError, SyntaxError) as exc:
        return False, str(exc)
    if not problems:
        return True, "\n".join(
            [
                *lines,
                "OK: every receivable message has a handler; every send is allowed (not-understood always)",
            ]
        )
    return False, "\n".join([*lines, *(f"- {p}" for p in problems), f"{len(problems)} problem(s)"])
