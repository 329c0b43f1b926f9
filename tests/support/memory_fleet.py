"""All six agents in one process on a MemoryBus, each running its FSM in its own thread."""

from __future__ import annotations

import queue
import threading
from typing import Any, Self

import msgspec

from services.agents.coordinator.agent import Coordinator
from services.agents.executor.agent import ExecutorAgent
from services.agents.human_interface.agent import HumanInterface
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.planner.agent import Planner
from services.agents.task_executor.agent import TaskExecutor
from services.monitor import is_world_update
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport
from services.runtime.memory_transport import MemoryBus
from tests.support.fake_executor import FakeExecutor


class MemoryFleet:
    def __init__(self, executor: Any | None = None) -> None:
        self.bus = MemoryBus()
        self.executor = executor or FakeExecutor()
        fake = self.executor

        class TestExecutorAgent(ExecutorAgent):
            def make_executor(self) -> Any:
                return fake

        self.agents: list[Agent] = [
            cls(self.bus.transport())
            for cls in (
                KnowledgeManager,
                Planner,
                Coordinator,
                TestExecutorAgent,
                TaskExecutor,
                HumanInterface,
            )
        ]
        self.reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
        dec = msgspec.json.Decoder(HumanReport)
        self.bus.subscribe(keys.HUMAN_OUT, lambda k, p: self.reports.put(dec.decode(p)))
        self.threads: list[threading.Thread] = []
        self.knowledge = threading.Event()
        self.bus.subscribe(keys.fipa_key("C6", "a_ta", "a_km"), self._on_c6)

    def _on_c6(self, _key: str, payload: bytes) -> None:
        # the first observation, not a_ta's agree to a_km's subscription
        if is_world_update(payload):
            self.knowledge.set()

    def agent(self, name: str) -> Agent:
        return next(a for a in self.agents if a.name == name)

    def __enter__(self) -> Self:
        for a in self.agents:
            a.engine.bind()
        for a in self.agents:
            t = threading.Thread(target=a.engine.run, name=a.name, daemon=True)
            t.start()
            self.threads.append(t)
        return self

    def __exit__(self, *exc: object) -> None:
        for a in self.agents:
            a.engine.stop()
        for t in self.threads:
            t.join(timeout=5)

    def wait_for_initial_knowledge(self, timeout: float = 10.0) -> None:
        """Block until a_ta has sent a_km its first observation (paper Table 7, 0–37 s)."""
        if not self.knowledge.wait(timeout):
            raise TimeoutError("no initial knowledge")

    def command(self, text: str, request_id: str = "r1", timeout: float = 30.0) -> list[HumanReport]:
        """Send a sentence to a_hi; return its reports up to the final one."""
        self.bus.publish(keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=text, request_id=request_id)))
        out = []
        while True:
            report = self.reports.get(timeout=timeout)
            if report.request_id != request_id:
                continue
            out.append(report)
            if report.kind in FINAL_REPORTS:
                return out
