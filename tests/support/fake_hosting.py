"""Doubles of the scenario runner's hosting (services/scenario/runner.py ``hosting``): a fleet
whose processes exit when a test says so and start again when the runner asks, without any
process. Used by tests/scenario/test_runner_restarts.py and test_runner_spec.py."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class FakeProcess:
    """A process of the fake fleet: its pid, and its exit code once a test ends it."""

    pid: int
    returncode: int | None = None

    def poll(self) -> int | None:
        return self.returncode


@dataclass
class FakeFleet:
    """A fleet whose processes exit when a test says so; ``restart`` starts a new one."""

    processes: dict[str, Any] = field(default_factory=dict)
    restarted: list[str] = field(default_factory=list)

    def dead(self) -> list[str]:
        return [n for n, p in self.processes.items() if p.poll() is not None]

    def restart(self, name: str) -> int:
        self.restarted.append(name)
        self.processes[name] = FakeProcess(self.processes[name].pid + 1)
        return int(self.processes[name].pid)


@dataclass
class FakeHosting:
    """Starts a service again as the local hosting does (services/fault/process.py ``start``)."""

    fleet: FakeFleet

    def start_again(self, session: object, service: str, timeout: float) -> None:
        self.fleet.restart(service)
