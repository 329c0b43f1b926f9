"""Acting on a timer (services/runtime/behaviour.py ``Every``, ``periodic``): a periodic
behaviour's transition function acts once its period has elapsed, and the agent blocks no
longer than until the next period is due. Time is a clock the test moves."""

from __future__ import annotations

import math

import pytest

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Every, periodic
from services.runtime.memory_transport import MemoryBus
from tests.support.role_agents import SPEC


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_every_holds_once_per_period_on_a_fixed_grid_and_skips_missed_periods() -> None:
    clock = Clock()
    every = Every(2.0, clock=clock)
    assert every.left() == 0.0  # before the first call: due
    assert every()  # at once
    assert not every()
    assert every.left() == pytest.approx(2.0)
    clock.t += 1.5
    assert not every() and every.left() == pytest.approx(0.5)
    clock.t += 0.6  # 2.1 s after the first: due since 0.1 s
    assert every()
    assert every.left() == pytest.approx(1.9)  # the grid, not 2 s after this call
    clock.t += 7.0  # 9.1 s: periods at 4 s, 6 s and 8 s missed; one firing, next at 10 s
    assert every() and not every()
    assert every.left() == pytest.approx(0.9)


def test_every_may_wait_a_period_first_and_refuses_a_period_that_is_not_positive() -> None:
    clock = Clock()
    every = Every(0.5, at_start=False, clock=clock)
    assert not every()
    clock.t += 0.5
    assert every()
    for bad in (0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="a period must be a positive number of seconds"):
            Every(bad)


def test_a_periodic_behaviour_serves_at_every_iteration_and_acts_when_its_period_elapsed() -> None:
    clock = Clock()
    done: list[str] = []
    b = periodic("watch", 3.0, lambda: done.append("act"), serve=lambda: done.append("serve"), clock=clock)
    assert b.waits and b.timer is not None and b.doc == "every 3 s"
    b.transition()
    b.transition()
    clock.t += 3.0
    b.transition()
    assert done == ["serve", "act", "serve", "serve", "act"]


class Ticker(Agent):
    """An agent whose one behaviour acts every 30 ms: less than its sampling period."""

    name = "a_i"

    def __init__(self, clock: Clock) -> None:
        self.clock = clock
        self.acted = 0
        super().__init__(MemoryBus().transport(), SPEC)

    def build_fsm(self) -> FSM:
        return FSM([periodic("tick", 0.03, self._act, clock=self.clock)])

    def _act(self) -> None:
        self.acted += 1


def test_the_agent_blocks_no_longer_than_until_the_next_period_is_due() -> None:
    clock = Clock()
    agent = Ticker(clock)
    assert agent.period == pytest.approx(0.1)
    actions = agent.engine._elementary_actions()
    wait = next(actions)  # the first iteration acted, then the agent blocks for input
    assert agent.acted == 1
    assert wait == pytest.approx(0.03)  # not the sampling period, 0.1 s
    clock.t += 0.01
    assert next(actions) == pytest.approx(0.02) and agent.acted == 1
    clock.t += 0.02
    assert next(actions) == pytest.approx(0.03) and agent.acted == 2
    actions.close()
