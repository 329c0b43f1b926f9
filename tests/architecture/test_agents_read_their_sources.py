"""Every agent reads its clocks and draws its randomness from ``Agent.sources``
(services/runtime/sources.py), so that ``roco replay`` can give it a clock set from the traffic
record and seeded random bytes and replay it exactly (docs/agents.md, "How an agent runs").

The agents' code is read (Python's ``ast``; nothing is run): no call of ``time.time``,
``time.monotonic``, ``time.perf_counter``, ``os.urandom``, ``random.*``, ``uuid.*``,
``datetime.now``/``utcnow`` or the codec's ``new_id``, and no import of ``random`` or ``uuid``;
a periodic behaviour (``periodic``) is given no ``clock=``: the runtime gives it the agent's
clock (the simulation's pace, or with ``wall=True`` the agent's wall clock, both read through
``Agent.sources``: services/runtime/behaviour.py ``Every.bind``); a timer used as a condition
(``Every``), which the runtime does not see, is given ``clock=`` (``self.fleet_clock`` or
``self.sources.monotonic``). ag_ex is left out: it paces the simulated robot on the wall clock.
A failure names each place as ``file:line``."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
AGENTS = ROOT / "services" / "agents"
EXEMPT = ("executor",)
"""Agent folders left out: ag_ex drives the simulation in wall-clock time."""
CLOCK_CALLS = {
    ("time", "time"),
    ("time", "monotonic"),
    ("time", "perf_counter"),
    ("os", "urandom"),
    ("datetime", "now"),
    ("datetime", "utcnow"),
}
"""(object, attribute) calls that read the system's clock or randomness."""
RANDOM_MODULES = ("random", "uuid", "secrets")


def _dotted(func: ast.expr) -> tuple[str, str] | None:
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
        return func.value.id, func.attr
    return None


def problems(source: str, path: str) -> list[str]:
    """Where ``source`` reads time or randomness other than through ``self.sources``."""
    found = []
    for node in ast.walk(ast.parse(source, path)):
        where = f"{path}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.Import):
            found += [f"{where}: import {a.name}" for a in node.names if a.name in RANDOM_MODULES]
        elif isinstance(node, ast.ImportFrom):
            names = {a.name for a in node.names}
            if node.module in RANDOM_MODULES or (node.module == "time" and names & {"time", "monotonic"}):
                found.append(f"{where}: from {node.module} import {', '.join(sorted(names))}")
            if "new_id" in names:
                found.append(f"{where}: imports new_id (use self.sources.new_id)")
        elif isinstance(node, ast.Call):
            dotted = _dotted(node.func)
            if dotted in CLOCK_CALLS or (dotted is not None and dotted[0] in RANDOM_MODULES):
                found.append(f"{where}: {'.'.join(dotted)}() (use self.sources)")
            name = node.func.id if isinstance(node.func, ast.Name) else ""
            clocked = any(k.arg == "clock" for k in node.keywords)
            if name == "periodic" and clocked:
                found.append(
                    f"{where}: periodic(…, clock=…) (the runtime gives the clock; wall=True: wall time)"
                )
            if name == "Every" and not clocked:
                found.append(
                    f"{where}: Every(…) without clock= (give it self.fleet_clock or self.sources.monotonic)"
                )
    return found


def test_agents_read_time_and_randomness_from_their_sources() -> None:
    found = []
    for path in sorted(AGENTS.rglob("*.py")):
        if path.relative_to(AGENTS).parts[0] in EXEMPT:
            continue
        found += problems(path.read_text(), path.relative_to(ROOT).as_posix())
    assert not found, "\n".join(found)


def test_the_check_finds_each_kind_of_read() -> None:
    planted = """
import random
from shared.fipa_codec.message import new_id
import time, os
a = time.monotonic()
b = os.urandom(6)
c = random.random()
d = periodic("tick", 1.0, act, clock=self.sources.monotonic)
e = periodic("tick", 1.0, act, wall=True)
f = self.sources.time()
g = Every(2.0)
h = Every(2.0, clock=self.fleet_clock)
"""
    lines = sorted(p.split(":")[1] for p in problems(planted, "planted.py"))
    assert lines == ["11", "2", "3", "5", "6", "7", "8"], problems(planted, "planted.py")
