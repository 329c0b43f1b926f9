"""Every agent takes its whole API of the runtime from two modules: services/runtime/agent.py
(the agent, its behaviours, a received communicate, the keys, the person's side of a_hi) and
services/runtime/roles/ (its protocol roles). Every import counts: at module level, under
``TYPE_CHECKING`` and inside functions; ``from services.runtime import keys`` imports
``services.runtime.keys``.
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.architecture.test_import_graph import AGENTS

ROOT = Path(__file__).resolve().parents[2]
FRONT_DOORS = frozenset({"services.runtime.agent", "services.runtime.roles"})


def runtime_imports(paths: list[Path]) -> dict[str, set[str]]:
    """Each runtime module imported by ``paths`` → where (``file:line``)."""
    out: dict[str, set[str]] = {}
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names: list[str] = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                if node.module == "services.runtime":
                    names = [f"services.runtime.{a.name}" for a in node.names]
                else:
                    names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            where = f"{path.relative_to(path.parents[1])}:{getattr(node, 'lineno', 0)}"
            for name in names:
                if name == "services.runtime" or name.startswith("services.runtime."):
                    out.setdefault(name, set()).add(where)
    return out


def test_every_agent_imports_the_runtime_from_two_modules() -> None:
    for agent in AGENTS:
        files = sorted((ROOT / "services" / "agents" / agent).rglob("*.py"))
        assert files, agent
        extra = {m: w for m, w in runtime_imports(files).items() if m not in FRONT_DOORS}
        assert not extra, f"services/agents/{agent} imports the runtime beyond agent.py and roles/: {extra}"


def test_an_import_of_a_third_runtime_module_is_found(tmp_path: Path) -> None:
    """The planted fault: an agent module that takes ``FSM`` from behaviour.py, and ``keys``
    inside a function."""
    agent = tmp_path / "agent" / "x.py"
    agent.parent.mkdir()
    agent.write_text(
        "from services.runtime.agent import Agent\n"
        "from services.runtime.behaviour import FSM\n"
        "def f():\n    from services.runtime import keys\n"
    )
    found = runtime_imports([agent])
    assert set(found) - FRONT_DOORS == {"services.runtime.behaviour", "services.runtime.keys"}
