"""``roco spec verify-code``: every message an agent may receive by the specification has a
handler in that agent's code, and every message its code sends is allowed by the
specification (the paper's ClassInterfaceInfo check, §5.6).

The check reads the code, it does not run it. An agent's code is the package of its
``implementation`` (``services.agents.planner.agent:Planner`` → every module of ``services/agents/planner/``).
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

from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, interface, load

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


def verify_code_report(path: Path = DEFAULT_SPEC) -> tuple[bool, str]:
    """``roco spec verify-code``: (ok, the report's text)."""
    try:
        spec = load(path)
        problems: list[str] = []
        lines: list[str] = []
        for a in spec.agents:
            files = package_files(a.implementation)
            code, found = verify_agent(spec, a.name, files)
            problems += found
            lines.append(
                f"{a.name}: {len(files)} files; sends {', '.join(sorted(code.sends)) or 'nothing'}; "
                f"handles {', '.join(sorted(code.handles)) or 'nothing'}"
            )
    except SpecError as exc:
        return False, str(exc)
    if not problems:
        return True, "\n".join([*lines, "OK: every receivable message has a handler; every send is allowed"])
    return False, "\n".join([*lines, *(f"- {p}" for p in problems), f"{len(problems)} problem(s)"])
