"""Reading an agent's code for communication outside its protocol roles.

An agent that declares its roles (services/runtime/roles.py) sends only through them: a
conversation's ``reply``/``send``/``cancel``/``refuse_with`` or ``self.roles.open``, which the
protocol's state machine checks at run time. This module reads the code (Python's ``ast``; it
runs nothing) for what would bypass or blur that:

- a **raw send**: ``self.send``, ``self.reply``, ``self.fail``, ``self.not_understood``, a
  ``publish`` on the transport, a ``Communicate(...)`` built by hand, or a FIPA key
  (``keys.fipa_key``): the runtime's own tools, not an agent's;
- a **performative comparison**: ``x.performative is …``, ``… in (Performative.X, …)``, a
  ``match`` on a performative: the roles route what arrives by the state machine;
- a **performative the agent's roles may not send**: any ``Performative.X`` in its code (or
  under an alias of ``Performative``), directly or through a variable, that no declared role
  may send in its protocol;
- an **opening outside its roles**: ``self.roles.open("Ck", "protocol", …)`` naming a channel
  and protocol (as literals) where the agent declares no initiator role;
- a **handler not written yet**: a method marked ``@handles``/``@on_deadline`` that raises
  NotImplementedError (as ``roco spec new-agent`` writes them).

What it cannot see: a performative built from a string at run time (``Performative(name)``)
or a channel named through a variable; the roles check those when the agent sends.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from shared.fipa_codec.acts import Performative

RAW_SENDS = frozenset({"send", "reply", "fail", "not_understood", "_out"})
"""Methods of :class:`~services.runtime.agent.Agent` an agent with roles does not call."""


@dataclass(frozen=True)
class Finding:
    """One thing the scan found: ``where`` (``file:line``) and what, as a sentence."""

    where: str
    text: str

    def __str__(self) -> str:
        return f"{self.text} ({self.where})"


def _aliases(tree: ast.AST) -> frozenset[str]:
    """The names ``Performative`` goes by in a module: itself, ``import … Performative as P``,
    ``P = Performative``."""
    names = {"Performative"}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            names |= {a.asname for a in node.names if a.name == "Performative" and a.asname}
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Name) and node.value.id in names:
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return frozenset(names)


_NAMES: frozenset[str] = frozenset({"Performative"})


def _performative(node: ast.AST, names: frozenset[str] = _NAMES) -> Performative | None:
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in names:
        try:
            return Performative[node.attr]
        except KeyError:
            return None
    return None


def _is_self(node: ast.AST, *attrs: str) -> bool:
    """``node`` is ``self`` (no ``attrs``) or ``self.<attrs[0]>.<attrs[1]>…``."""
    for attr in reversed(attrs):
        if not (isinstance(node, ast.Attribute) and node.attr == attr):
            return False
        node = node.value
    return isinstance(node, ast.Name) and node.id == "self"


def _names_performative(node: ast.AST, names: frozenset[str] = _NAMES) -> bool:
    return _performative(node, names) is not None or (
        isinstance(node, ast.Attribute) and node.attr == "performative"
    )


def scan(
    files: Iterable[Path],
    may_send: frozenset[Performative],
    opens: frozenset[tuple[str, str]],
) -> list[Finding]:
    """What in ``files`` bypasses the agent's roles (see the module docstring). ``may_send``
    are the performatives its declared roles may send; ``opens`` the (channel, protocol) where
    it is the initiator. Raises SyntaxError for a file that does not parse."""
    out: list[Finding] = []
    for path in files:
        tree = ast.parse(path.read_text(), str(path))
        names = _aliases(tree)
        for node in ast.walk(tree):
            where = f"{path.name}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Call):
                out += _call(node, where, opens)
            elif isinstance(node, ast.Compare):
                operands = [node.left, *node.comparators]
                elements = [
                    el
                    for op in operands
                    for el in (op.elts if isinstance(op, ast.Tuple | ast.Set | ast.List) else [op])
                ]
                if any(_names_performative(el, names) for el in elements):
                    out.append(Finding(where, "compares a performative (the roles route what arrives)"))
            elif isinstance(node, ast.Match) and _names_performative(node.subject, names):
                out.append(Finding(where, "matches on a performative (the roles route what arrives)"))
            elif isinstance(node, ast.FunctionDef) and _is_handler(node) and _unwritten(node):
                out.append(
                    Finding(where, f"has a handler not written yet: {node.name} raises NotImplementedError")
                )
            perf = _performative(node, names)
            if perf is not None and perf not in may_send:
                out.append(Finding(where, f"uses Performative.{perf.name}, which none of its roles may send"))
    return out


def _is_handler(node: ast.FunctionDef) -> bool:
    for dec in node.decorator_list:
        func = dec.func if isinstance(dec, ast.Call) else dec
        name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""
        if name in ("handles", "on_deadline"):
            return True
    return False


def _unwritten(node: ast.FunctionDef) -> bool:
    for sub in ast.walk(node):
        if isinstance(sub, ast.Raise) and sub.exc is not None:
            exc = sub.exc.func if isinstance(sub.exc, ast.Call) else sub.exc
            if isinstance(exc, ast.Name) and exc.id == "NotImplementedError":
                return True
    return False


def _call(node: ast.Call, where: str, opens: frozenset[tuple[str, str]]) -> list[Finding]:
    func = node.func
    if isinstance(func, ast.Name) and func.id == "Communicate":
        return [Finding(where, "builds a Communicate by hand (only its roles send)")]
    if not isinstance(func, ast.Attribute):
        return []
    if func.attr in RAW_SENDS and _is_self(func.value):
        first = node.args[0] if node.args else None
        peer = first.value if isinstance(first, ast.Constant) and isinstance(first.value, str) else None
        to = f" to {peer}" if peer is not None and func.attr == "send" else ""
        return [Finding(where, f"sends with self.{func.attr}{to} outside its roles")]
    if func.attr == "publish":
        return [Finding(where, "publishes on the transport (only its roles send; self.emit for effectors)")]
    if func.attr == "fipa_key":
        return [Finding(where, "names a FIPA key (only its roles send)")]
    if func.attr == "open" and _is_self(func.value, "roles") and len(node.args) >= 2:
        channel, protocol = node.args[0], node.args[1]
        if (
            isinstance(channel, ast.Constant)
            and isinstance(protocol, ast.Constant)
            and isinstance(channel.value, str)
            and isinstance(protocol.value, str)
            and (channel.value, protocol.value) not in opens
        ):
            return [
                Finding(
                    where,
                    f"opens {protocol.value} on {channel.value}, where it declares no initiator role",
                )
            ]
    return []


def findings_text(findings: Sequence[Finding], agent: str) -> list[str]:
    """One line per finding, naming the agent."""
    return [f"agent {agent} {f}" for f in findings]
