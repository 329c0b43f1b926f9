"""a_ta keeps only its decisions of the coordinate protocol: its participant role sends the
L_SW informs one at a time until a_co confirmed each (``confirmed_informs=True``,
services/runtime/roles/confirmed.py), so a_ta's code, read by AST,

- handles no ``confirm`` (the role takes it),
- and sends no ``inform`` in a conversation itself (``<conversation>.send(Performative.INFORM, …)``;
  it reports through ``self.reports.inform``; answering a_km's subscription is ``reply``).

(Its memory is made in ``__init__``, as every agent's: test_agents_make_memory_in_init.py.)
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TASK_EXECUTOR = ROOT / "services" / "agents" / "task_executor"


def _handles_confirm(fn: ast.FunctionDef) -> bool:
    return any(
        isinstance(d, ast.Call)
        and ast.unparse(d.func) == "handles"
        and any(ast.unparse(a) == "Performative.CONFIRM" for a in d.args)
        for d in fn.decorator_list
    )


def _sends_inform(call: ast.Call) -> bool:
    return (
        isinstance(call.func, ast.Attribute)
        and call.func.attr == "send"
        and bool(call.args)
        and ast.unparse(call.args[0]) == "Performative.INFORM"
    )


def findings(source: str, name: str = "<source>") -> list[tuple[int, str]]:
    """(line, what) for each piece of the confirm loop."""
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source, name)):
        if isinstance(node, ast.FunctionDef) and _handles_confirm(node):
            out.append((node.lineno, f"{node.name} handles confirm"))
        elif isinstance(node, ast.Call) and _sends_inform(node):
            out.append((node.lineno, f"sends an inform itself ({ast.unparse(node.func)})"))
    return sorted(out)


def test_a_ta_has_no_confirm_loop_of_its_own() -> None:
    found = {
        f"{path.name}:{line}: {what}"
        for path in sorted(TASK_EXECUTOR.rglob("*.py"))
        for line, what in findings(path.read_text(), str(path))
    }
    assert not found, "\n".join(sorted(found))


PLANTED = """
class TaskExecutor(Agent):
    @handles(COORDINATE, PARTICIPANT, Performative.CONFIRM)
    def _on_confirm(self, conv: Conversation) -> None:
        self.awaiting = None

    def _flush_sw(self) -> None:
        self.awaiting = self.plan_request.send(Performative.INFORM, self.sw_queue.popleft(), retry_s=5.0)
"""


def test_the_confirm_loop_as_a_ta_once_wrote_it_is_found() -> None:
    """The planted fault: a_ta's own loop before the role kept it."""
    assert [what for _, what in findings(PLANTED)] == [
        "_on_confirm handles confirm",
        "sends an inform itself (self.plan_request.send)",
    ]
