"""Every agent creates its memory (the attributes that persist across steps, paper §3.2) in
``__init__``, where a reader looks for it, and ``build_fsm`` only builds the FSM: read by AST,
no ``build_fsm`` of a module under services/agents/ assigns an attribute of ``self``
(``self.x = …``, ``self.x: T = …``, ``self.x += …``, ``self.x, self.y = …``).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
AGENTS = ROOT / "services" / "agents"


def _self_attributes(target: ast.expr) -> list[ast.Attribute]:
    """The ``self.<attribute>`` targets in ``target``, unpacked tuples and lists included."""
    if isinstance(target, ast.Attribute) and ast.unparse(target.value) == "self":
        return [target]
    if isinstance(target, ast.Tuple | ast.List):
        return [a for t in target.elts for a in _self_attributes(t)]
    if isinstance(target, ast.Starred):
        return _self_attributes(target.value)
    return []


def _made_in(fn: ast.FunctionDef) -> list[tuple[int, str]]:
    """(line, attribute) of each ``self.<attribute>`` that ``fn`` assigns."""
    out = []
    for node in ast.walk(fn):
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AnnAssign | ast.AugAssign):
            targets = [node.target]
        out += [(a.lineno, a.attr) for t in targets for a in _self_attributes(t)]
    return out


def findings(source: str, name: str = "<source>") -> list[tuple[int, str]]:
    """(line, what) for each attribute of ``self`` a ``build_fsm`` in ``source`` assigns."""
    return sorted(
        (line, f"{cls.name}.build_fsm creates self.{attr}")
        for cls in ast.walk(ast.parse(source, name))
        if isinstance(cls, ast.ClassDef)
        for fn in cls.body
        if isinstance(fn, ast.FunctionDef) and fn.name == "build_fsm"
        for line, attr in _made_in(fn)
    )


def test_no_agent_creates_memory_in_build_fsm() -> None:
    found = [
        f"{path.relative_to(ROOT)}:{line}: {what}"
        for path in sorted(AGENTS.rglob("*.py"))
        for line, what in findings(path.read_text(), str(path))
    ]
    assert not found, "memory belongs in __init__:\n" + "\n".join(found)


def test_every_agent_builds_an_fsm_where_the_check_reads() -> None:
    """The check reads the agents' build_fsm: each of the six agents has one there."""
    built = {
        cls.name
        for path in AGENTS.rglob("*.py")
        for cls in ast.walk(ast.parse(path.read_text()))
        if isinstance(cls, ast.ClassDef)
        and any(isinstance(f, ast.FunctionDef) and f.name == "build_fsm" for f in cls.body)
    }
    assert {
        "Coordinator",
        "ExecutorAgent",
        "HumanInterface",
        "KnowledgeManager",
        "Planner",
        "TaskExecutor",
    } <= built


PLANTED = """
class Coordinator(Agent):
    def build_fsm(self) -> FSM:
        self.ta_lost = False
        self.tasks: dict[str, Task] = {}
        self.progress = self.roles.serve(C2, FIPA_SUBSCRIBE, unsent=list)
        self.decision, self.reschedule = Decision(None, False, ""), False
        self.replans += 1
        return FSM([Behaviour("trigger", self.handle_received, terminal=self._has_work)])

    def _schedule(self) -> None:
        self.reschedule = False
"""


def test_memory_made_in_build_fsm_as_a_co_once_made_it_is_found() -> None:
    """The planted fault: a_co's build_fsm as it was before its memory moved to ``__init__``
    (an assignment in another method is no finding)."""
    assert [what for _, what in findings(PLANTED)] == [
        "Coordinator.build_fsm creates self.ta_lost",
        "Coordinator.build_fsm creates self.tasks",
        "Coordinator.build_fsm creates self.progress",
        "Coordinator.build_fsm creates self.decision",
        "Coordinator.build_fsm creates self.reschedule",
        "Coordinator.build_fsm creates self.replans",
    ]
