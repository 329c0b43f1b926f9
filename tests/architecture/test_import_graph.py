"""The import graph among roco's packages: each layer imports only those below it (README.md,
"How it is built"), and no package imports another package that imports it back.

A package is a folder directly under ``shared/``, ``services/`` or ``velma/`` (or a module
there: ``services/fleet_state.py``), and each agent's folder under ``services/agents/``. The
agents are those of the specification, the tools every other package under ``services/`` above
the bottom layers (services/cli/, the command line, among them: tests/architecture/
test_cli_assembles.py keeps every tool from importing it): a new one is checked without an edit
here. Every ``import`` of roco code counts, also those inside functions and under
``TYPE_CHECKING``.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

from services.spec.model import default_spec

ROOT = Path(__file__).resolve().parents[2]
TOPS = ("shared", "services", "velma")

LAYERS = {
    "shared.fipa_codec": set(),
    "shared.settings": set(),
    "shared.ready_file": set(),
    "services.spec": {"shared.fipa_codec", "shared.settings"},
    "services.security": {"shared.settings"},
    "services.runtime": {
        "shared.fipa_codec",
        "shared.settings",
        "shared.ready_file",
        "services.spec",
        "services.security",
    },
}
"""The bottom layers and everything each may import (README.md, "How it is built": the codec and
the settings, the readiness file, the specification's data model, the credentials' format, the
agent runtime)."""
AGENTS = tuple(sorted({a.implementation.split(":")[0].split(".")[2] for a in default_spec().agents}))
"""The agents' packages (``services.agents.<name>``), from the specification's agents."""


def _tools() -> tuple[str, ...]:
    """Every package under services/ (a folder, or a module such as services/fleet_state.py) that is
    neither a bottom layer nor an agent nor services/agents itself."""
    found = set()
    for path in (ROOT / "services").iterdir():
        if path.name.startswith(("_", ".")) or not (path.is_dir() or path.suffix == ".py"):
            continue
        if path.is_dir() and not any(path.rglob("*.py")):
            continue
        found.add(f"services.{path.stem}")
    return tuple(sorted(found - set(LAYERS) - {"services.agents"}))


TOOLS = _tools()
"""The tools (README.md, "How it is built": layer 5 and the CLI), from the tree."""


def package_of(module: str) -> str | None:
    """``services.runtime.agent`` → ``services.runtime``, ``services.agents.planner.domain`` →
    ``services.agents.planner`` (each agent is a package of its own); None outside roco."""
    parts = module.split(".")
    if parts[0] not in TOPS or len(parts) < 2:
        return None
    if parts[:2] == ["services", "agents"] and len(parts) > 2:
        return ".".join(parts[:3])
    return ".".join(parts[:2])


def import_graph() -> dict[str, set[str]]:
    """Package → the other roco packages its modules import."""
    edges: dict[str, set[str]] = defaultdict(set)
    for top in TOPS:
        for path in (ROOT / top).rglob("*.py"):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            source = package_of(module.removesuffix(".__init__"))
            if source is None:
                continue
            edges[source]
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                names = []
                if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                    names = [node.module]
                elif isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                for name in names:
                    target = package_of(name)
                    if target is not None and target != source:
                        edges[source].add(target)
    return edges


def cycles(edges: dict[str, set[str]]) -> set[frozenset[str]]:
    """The strongly connected components of more than one package (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: set[frozenset[str]] = set()

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.add(frozenset(component))

    for v in list(edges):
        if v not in index:
            visit(v)
    return found


def test_the_package_graph_has_no_cycle() -> None:
    assert cycles(import_graph()) == set()


def test_the_bottom_layers_import_only_what_is_below_them() -> None:
    graph = import_graph()
    for package, allowed in LAYERS.items():
        assert graph[package] <= allowed, (package, graph[package] - allowed)


def test_neither_the_runtime_nor_an_agent_imports_a_tool() -> None:
    graph = import_graph()
    for package in ("services.runtime", *(f"services.agents.{a}" for a in AGENTS)):
        assert not graph[package] & set(TOOLS), (package, graph[package] & set(TOOLS))


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == {frozenset("abc")}
    assert cycles({"a": {"b"}, "b": set()}) == set()


def test_agents_receive_the_viewer_and_do_not_import_it() -> None:
    graph = import_graph()
    for agent in AGENTS:
        assert "services.viewer" not in graph[f"services.agents.{agent}"], agent
    # the recorder and the viewer do not import each other
    assert "services.viewer" not in graph["services.recorder"]
    assert "services.recorder" not in graph["services.viewer"]


def test_the_codec_and_the_robot_import_nothing_above_them() -> None:
    graph = import_graph()
    assert graph["shared.fipa_codec"] <= set()
    assert graph["shared.settings"] <= set()
    assert graph["shared.ready_file"] <= set()
    for package, imports in graph.items():
        if package.startswith("velma."):
            assert all(p.startswith(("velma.", "shared.")) for p in imports), (package, imports)


def test_agents_never_import_one_another() -> None:
    """They only talk in communicates (paper §3.2: what other agents send reaches an agent through
    its transmission input buffer)."""
    graph = import_graph()
    agents = {f"services.agents.{a}" for a in AGENTS}
    for agent in agents:
        assert not graph[agent] & agents, (agent, graph[agent] & agents)


def test_tools_speak_to_agents_and_do_not_import_them() -> None:
    """The CLI, the scenario runner and the viewer reach agents through Zenoh only (the person's
    side of a_hi is services/runtime/human.py); only the benchmarks run an agent's parts in
    process (services/bench: a_km's world model; a_pl's plan #1 of the pour, the one the
    planning part must time; a_ta's inform of an observation, the scene it gives a_km)."""
    graph = import_graph()
    for tool in (t for t in TOOLS if t != "services.bench"):
        imported = {p for p in graph[tool] if p.startswith("services.agents.")}
        assert not imported, (tool, imported)
    assert {p for p in graph["services.bench"] if p.startswith("services.agents.")} == {
        "services.agents.knowledge",
        "services.agents.planner",
        "services.agents.task_executor",
    }


def test_the_agents_are_the_specifications_and_the_tools_the_trees() -> None:
    """Each agent's package is a folder under services/agents/ and each folder there an agent's;
    the tools found in the tree include those the graph names."""
    tree = {
        p.name
        for p in (ROOT / "services" / "agents").iterdir()
        if p.is_dir() and (p / "__init__.py").exists()
    }
    assert set(AGENTS) == tree, set(AGENTS) ^ tree
    assert {"services.cli", "services.bench", "services.fleet"} <= set(TOOLS)
    graph = import_graph()
    services = {p for p in graph if p.startswith("services.") and not p.startswith("services.agents")}
    assert services == set(TOOLS) | set(LAYERS) - {p for p in LAYERS if not p.startswith("services.")}
