"""No agent carries protocol machinery by hand (README: "an agent never compares
performatives nor keeps a book of replies"; beside JADE's jade.proto, where a protocol object
per conversation carries its context): the roles own it (services/runtime/roles/).

Read by AST, every agent module of the specification must not

- define a msgspec Struct or a dataclass whose name starts with ``Kept`` (what a role must
  remember across a restart is declared with the role, ``keep=``; the runtime keeps it),
- build a ``StateFile`` itself (the same: services/runtime/state_store.py),
- read ``.reply_with`` or ``.in_reply_to`` (the roles route replies; a repeated request is
  recognised by the role, ``Conversation.repeats``; what a reply answers is
  ``Conversation.last_answers``),
- open a fipa-subscribe conversation itself (``self.roles.open(…, FIPA_SUBSCRIBE, …)``: a
  subscribe back-off by hand; ``Roles.subscribe`` keeps a subscription open).

An exception would be listed in ``ALLOWED`` with why, one line each (none is left: a_ta's
restart state was the last moved); an entry that no longer occurs fails too, so that the list
only shrinks.
"""

from __future__ import annotations

import ast
from pathlib import Path

from services.spec.model import default_spec
from services.spec_check.code_check import package_files

ROOT = Path(__file__).resolve().parents[2]

ALLOWED: dict[tuple[str, str], str] = {}


def _is_struct_or_dataclass(node: ast.ClassDef) -> bool:
    bases = [ast.unparse(b) for b in node.bases]
    decorators = [ast.unparse(d) for d in node.decorator_list]
    return any("Struct" in b for b in bases) or any(d.split("(")[0].endswith("dataclass") for d in decorators)


def findings(path: Path) -> list[tuple[int, str]]:
    """(line, what) for each piece of protocol machinery written by hand in ``path``."""
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ClassDef) and node.name.startswith("Kept") and _is_struct_or_dataclass(node):
            out.append((node.lineno, f"defines {node.name}"))
        elif isinstance(node, ast.Attribute) and node.attr in ("reply_with", "in_reply_to"):
            out.append((node.lineno, f"reads .{node.attr}"))
        elif isinstance(node, ast.Call):
            func = ast.unparse(node.func)
            if func == "StateFile" or func.startswith("StateFile."):
                out.append((node.lineno, "builds a StateFile"))
            elif func.endswith("roles.open") and len(node.args) > 1:
                protocol = node.args[1]
                named = ast.unparse(protocol)
                if named == "FIPA_SUBSCRIBE" or (
                    isinstance(protocol, ast.Constant) and protocol.value == "fipa-subscribe"
                ):
                    out.append((node.lineno, "opens a fipa-subscribe by hand"))
    return sorted(out)


def _agent_files() -> list[Path]:
    files: set[Path] = set()
    for agent in default_spec().agents:
        files.update(package_files(agent.implementation))
    return sorted(files)


def test_no_agent_module_keeps_protocol_state_by_hand() -> None:
    found: list[str] = []
    seen: set[tuple[str, str]] = set()
    for path in _agent_files():
        rel = path.relative_to(ROOT).as_posix()
        for line, what in findings(path):
            if (rel, what) in ALLOWED:
                seen.add((rel, what))
                continue
            found.append(f"{rel}:{line}: {what}")
    assert found == [], "protocol machinery by hand (see this test's docstring):\n" + "\n".join(found)
    gone = [f"{rel}: {what}" for rel, what in ALLOWED if (rel, what) not in seen]
    assert gone == [], "allowed but no longer found, take them off ALLOWED:\n" + "\n".join(gone)


def test_the_check_finds_what_it_names(tmp_path: Path) -> None:
    sample = tmp_path / "agent.py"
    sample.write_text(
        "import msgspec\n"
        "from dataclasses import dataclass\n"
        "class KeptThing(msgspec.Struct):\n"
        "    x: int\n"
        "@dataclass\n"
        "class KeptOther:\n"
        "    y: int\n"
        "class KeptName:\n"  # neither a Struct nor a dataclass: a name only
        "    pass\n"
        "def f(self, conv):\n"
        "    self.kept = StateFile.for_agent(self.name, KeptThing)\n"
        "    if conv.last.msg.reply_with == conv.opening.msg.in_reply_to:\n"
        "        self.roles.open(C2, FIPA_SUBSCRIBE, None)\n"
    )
    assert findings(sample) == [
        (3, "defines KeptThing"),
        (6, "defines KeptOther"),
        (11, "builds a StateFile"),
        (12, "reads .in_reply_to"),
        (12, "reads .reply_with"),
        (13, "opens a fipa-subscribe by hand"),
    ]


SHORTER = {"coordinator": 636, "human_interface": 694}
"""Lines of a_co's and a_hi's agent.py outside their handlers (:func:`outside_handlers`) when the
runtime took their protocol machinery over (729 and 825 lines in all then). What moved was
bookkeeping around the handlers (replies matched by hand, deadlines, kept conversations); each
stays at least a fifth shorter there, so that it does not come back. A handler (an ``@handles``
method: a decision of the agent) is not counted: an agent grows by handlers as its channels do."""


def outside_handlers(text: str) -> int:
    """Lines of module ``text`` outside its ``@handles`` methods (decorators included)."""
    inside: set[int] = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and any(
            ast.unparse(d).split("(")[0].split(".")[-1] == "handles" for d in node.decorator_list
        ):
            start = min(d.lineno for d in node.decorator_list)
            inside.update(range(start, (node.end_lineno or node.lineno) + 1))
    return len(text.splitlines()) - len(inside)


def _over_budget(folder: str, text: str) -> str | None:
    lines, budget = outside_handlers(text), int(0.8 * SHORTER[folder])
    return (
        f"{folder}/agent.py: {lines} lines outside its handlers, at most {budget}" if lines > budget else None
    )


def test_a_co_and_a_hi_stay_a_fifth_shorter_than_before_the_roles_took_their_protocols() -> None:
    for folder in SHORTER:
        problem = _over_budget(folder, (ROOT / "services" / "agents" / folder / "agent.py").read_text())
        assert problem is None, problem


HANDLER = (
    """    @handles(FIPA_QUERY, INITIATOR, Performative.INFORM_REF)
    def _on_scene(self, conv: Conversation) -> None:
        \"\"\"a_km's answer: what the kitchen holds now.\"\"\"
        if not isinstance(conv.content, Answer):
            return
        for thing in conv.content.objects:
            self.seen[thing.name] = thing
"""
    + "        self.counters['scenes'] += 1\n" * 14
)


def test_the_budget_takes_a_new_handler_and_not_bookkeeping_beside_the_handlers() -> None:
    for agent in default_spec().agents:
        folder = agent.implementation.split(".")[2]
        if folder not in SHORTER:
            continue
        text = (ROOT / "services" / "agents" / folder / "agent.py").read_text()
        head = f"class {agent.implementation.split(':')[1]}("
        cls = next(line for line in text.splitlines(keepends=True) if line.startswith(head))
        grown = text.replace(cls, cls + HANDLER, 1)  # a decision of ~20 lines more
        assert len(HANDLER.splitlines()) >= 20 and _over_budget(folder, grown) is None
        room = int(0.8 * SHORTER[folder]) - outside_handlers(text)
        book = "    def _book(self) -> None:\n" + "        self.replies_seen = {}\n" * room
        assert _over_budget(folder, text.replace(cls, cls + book, 1)) is not None
