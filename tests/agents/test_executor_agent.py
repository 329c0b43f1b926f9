"""ag_ex's communication side: it holds the robot when a_ta's liveliness token goes away, and
publishes the robot state (services/agents/executor/agent.py)."""

from __future__ import annotations

import queue
import threading
from typing import Any

import msgspec

from services.agents.executor.agent import ExecutorAgent
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from velma.executor.state import RobotSnapshot


class HoldingFake:
    """Records ``hold`` calls; reports a fixed state."""

    def __init__(self) -> None:
        self.holds: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.holding: str | None = None

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def submit(self, command: Any, on_done: Any) -> None: ...

    def hold(self, why: str) -> bool:
        self.holding = why
        self.holds.put(why)
        return True

    def snapshot(self) -> RobotSnapshot:
        return RobotSnapshot(
            sim_time=1.0,
            joints={"torso_0_joint": 0.0},
            grip={},
            held={"left": True},
            held_object={"left": "jar"},
            holding=self.holding,
        )


def test_holds_when_a_ta_disappears_and_publishes_state() -> None:
    bus = MemoryBus()
    fake = HoldingFake()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            return fake

    states: queue.SimpleQueue[RobotSnapshot] = queue.SimpleQueue()
    dec = msgspec.msgpack.Decoder(RobotSnapshot)
    bus.subscribe(keys.state_key("ag_ex"), lambda _k, p: states.put(dec.decode(p)))
    a_ta = bus.transport()
    a_ta.announce(keys.alive_key("a_ta"))
    agent = Ex(bus.transport())
    assert agent.commanders == ("a_ta",)  # from the specification's C5
    agent.bind()
    thread = threading.Thread(target=agent.run, daemon=True)
    thread.start()
    try:
        first = states.get(timeout=10)
        assert first.holding is None and first.held_object == {"left": "jar"}
        assert fake.holds.empty()
        a_ta.close()  # a_ta's session ends: its token is withdrawn
        assert fake.holds.get(timeout=10) == "a_ta lost"
        state = states.get(timeout=10)
        while state.holding is None:
            state = states.get(timeout=10)
        assert state.holding == "a_ta lost"
        assert agent.counters["holds"] == 1
    finally:
        agent.stop()
        thread.join(10)


def test_malformed_seed_is_a_clear_configuration_error(monkeypatch: Any) -> None:
    import pytest

    monkeypatch.setenv("ROCO_SEED", "abc")
    with pytest.raises(ValueError, match="ROCO_SEED='abc' is not an integer"):
        ExecutorAgent(MemoryBus().transport())
    monkeypatch.setenv("ROCO_SEED", "1")
    monkeypatch.setenv("ROCO_POSE_SEED", "-3")
    with pytest.raises(ValueError, match="ROCO_POSE_SEED=-3 is negative"):
        ExecutorAgent(MemoryBus().transport())
