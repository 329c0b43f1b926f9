"""Reading an agent's code for communication outside its protocol roles.

An agent that declares its roles (services/runtime/roles/) sends only through them: a
conversation's ``reply``/``send``/``cancel``/``refuse_with`` or ``self.roles.open``, which the
protocol's state machine checks at run time. This module reads the code (Python's ``ast``; it
runs nothing) for what would bypass or blur that:

- a **raw send**: the engine's ``send``, ``reply``, ``fail`` or ``not_understood``
  (``self.engine.send``; ``self.send`` on an agent of its own base), a
  ``publish`` on the transport, a ``Communicate(...)`` built by hand, or a FIPA key
  (``keys.fipa_key``): the runtime's own tools, not an agent's;
- a **performative comparison**: ``x.performative is …``, ``… in (Performative.X, …)``, a
  ``match`` on a performative: the roles route what arrives by the state machine;
- a **performative the agent's roles may not send**: any ``Performative.X`` in its code (or
  under an alias of ``Performative``), directly or through a variable, that no declared role
  may send in its protocol — but for those a handler's ``@handles(…)`` names: what it receives;
- an **opening outside its roles**: ``self.roles.open(C9, FIPA_QUERY, …)`` naming a channel
  and protocol where the agent declares no initiator role: by the names of
  services/spec/names.py (``C9``, ``Channel.C9``, ``names.C9``; read by ``spelling``, the
  specification's Python names → its spellings) or as string literals;
- a **handler not written yet**: a method marked ``@handles``/``@on_deadline`` that raises
  NotImplementedError (as ``roco spec new-agent`` writes them).

What it cannot see: a performative built from a string at run time (``Performative(name)``)
or a channel named through a variable of its own; the roles check those when the agent sends.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from shared.fipa_codec.acts import Performative

RAW_SENDS = frozenset({"send", "reply", "fail", "not_understood"})
"""Methods of services/runtime/engine.py ``Engine`` an agent with roles does not call."""


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

NAMES_MODULE = "services.spec.names"
"""The module of the specification's names (generated: services/spec/render_names.py)."""
NAMES_CLASSES = frozenset({"Channel", "ProtocolName", "Language"})
"""Its enums: ``Channel.C9`` names what the alias ``C9`` does."""


@dataclass(frozen=True)
class SpecNames:
    """How one module refers to services/spec/names.py: ``aliases`` (a local name → the
    specification's spelling it stands for: ``from services.spec.names import C9 as Nine``),
    ``holders`` (local names of the module itself or of its enums, whose attributes are
    names: ``names.C9``, ``Channel.C9``) and ``spelling`` (each Python name of the
    specification → its spelling)."""

    aliases: Mapping[str, str]
    holders: frozenset[str]
    spelling: Mapping[str, str]

    def value(self, node: ast.AST) -> str | None:
        """The string ``node`` names: a string literal, or a name of the specification by
        services/spec/names.py; None for anything else."""
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            return node.value
        if isinstance(node, ast.Name):
            return self.aliases.get(node.id)
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in self.holders
        ):
            return self.spelling.get(node.attr)
        return None


def spec_names(tree: ast.AST, spelling: Mapping[str, str]) -> SpecNames:
    """How module ``tree`` refers to services/spec/names.py (see :class:`SpecNames`), with
    ``spelling`` the specification's Python names → spellings
    (services/spec/render_names.py :func:`~services.spec.render_names.spellings`)."""
    aliases: dict[str, str] = {}
    holders: set[str] = set()
    package, _, leaf = NAMES_MODULE.rpartition(".")
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module == NAMES_MODULE:
            for a in node.names:
                if a.name in NAMES_CLASSES:
                    holders.add(a.asname or a.name)
                elif a.name in spelling:
                    aliases[a.asname or a.name] = spelling[a.name]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module == package:
            holders |= {a.asname or a.name for a in node.names if a.name == leaf}
        elif isinstance(node, ast.Import):
            holders |= {a.asname for a in node.names if a.name == NAMES_MODULE and a.asname}
    return SpecNames(aliases, frozenset(holders), spelling)


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
    spelling: Mapping[str, str] | None = None,
) -> list[Finding]:
    """What in ``files`` bypasses the agent's roles (see the module docstring). ``may_send``
    are the performatives its declared roles may send; ``opens`` the (channel, protocol) where
    it is the initiator; ``spelling`` the specification's Python names → spellings, by which
    the names of services/spec/names.py in an opening are read (None: only string literals
    are). Raises SyntaxError for a file that does not parse."""
    out: list[Finding] = []
    for path in files:
        tree = ast.parse(path.read_text(), str(path))
        names = _aliases(tree)
        named = spec_names(tree, spelling or {})
        received = _received(tree)
        for node in ast.walk(tree):
            where = f"{path.name}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Call):
                out += _call(node, where, opens, named)
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
            if perf is not None and perf not in may_send and id(node) not in received:
                out.append(Finding(where, f"uses Performative.{perf.name}, which none of its roles may send"))
    return out


def _received(tree: ast.AST) -> frozenset[int]:
    """The ids of the nodes in the arguments of every ``@handles(…)`` decorator of ``tree``:
    the performatives a handler receives, which its roles need not send."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for dec in node.decorator_list:
                if isinstance(dec, ast.Call) and _decorator_name(dec) == "handles":
                    out |= {id(sub) for arg in dec.args for sub in ast.walk(arg)}
    return frozenset(out)


def _decorator_name(dec: ast.expr) -> str:
    func = dec.func if isinstance(dec, ast.Call) else dec
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def _is_handler(node: ast.FunctionDef) -> bool:
    return any(_decorator_name(dec) in ("handles", "on_deadline") for dec in node.decorator_list)


def _unwritten(node: ast.FunctionDef) -> bool:
    for sub in ast.walk(node):
        if isinstance(sub, ast.Raise) and sub.exc is not None:
            exc = sub.exc.func if isinstance(sub.exc, ast.Call) else sub.exc
            if isinstance(exc, ast.Name) and exc.id == "NotImplementedError":
                return True
    return False


def _call(node: ast.Call, where: str, opens: frozenset[tuple[str, str]], named: SpecNames) -> list[Finding]:
    func = node.func
    if isinstance(func, ast.Name) and func.id == "Communicate":
        return [Finding(where, "builds a Communicate by hand (only its roles send)")]
    if not isinstance(func, ast.Attribute):
        return []
    if func.attr in RAW_SENDS and (_is_self(func.value) or _is_self(func.value, "engine")):
        first = node.args[0] if node.args else None
        peer = first.value if isinstance(first, ast.Constant) and isinstance(first.value, str) else None
        to = f" to {peer}" if peer is not None and func.attr == "send" else ""
        said = "self.engine" if _is_self(func.value, "engine") else "self"
        return [Finding(where, f"sends with {said}.{func.attr}{to} outside its roles")]
    if func.attr == "publish":
        return [Finding(where, "publishes on the transport (only its roles send; self.emit for effectors)")]
    if func.attr == "fipa_key":
        return [Finding(where, "names a FIPA key (only its roles send)")]
    if func.attr == "open" and _is_self(func.value, "roles") and len(node.args) >= 2:
        channel, protocol = named.value(node.args[0]), named.value(node.args[1])
        if channel is not None and protocol is not None and (channel, protocol) not in opens:
            return [Finding(where, f"opens {protocol} on {channel}, where it declares no initiator role")]
    return []


def findings_text(findings: Sequence[Finding], agent: str) -> list[str]:
    """One line per finding, naming the agent."""
    return [f"agent {agent} {f}" for f in findings]
