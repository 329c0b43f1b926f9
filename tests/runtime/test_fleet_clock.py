"""Periodic behaviours on the fleet's clock (services/runtime/clock.py, behaviour.py ``Every``):
while ag_ex's simulation time is heard, a period is one of the simulation's; a timer that asks
for the wall clock keeps wall time; in real time the agent does not listen. The wall clock is a
clock the test moves; nothing sleeps."""

from __future__ import annotations

import pytest

from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Every, periodic
from services.runtime.clock import STALE_S, FleetClock, decode_sim_time, encode_sim_time
from services.runtime.memory_transport import MemoryBus
from tests.support.role_agents import SPEC

FAST = 5.0
"""Simulation seconds per wall second: the fleet running as fast as possible."""
STEP = 0.05
"""Wall seconds between ag_ex's marks (its state rate, 20 Hz)."""


class Wall:
    """A monotonic wall clock the test moves (s)."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Sources:
    """An agent's sources whose clocks are :class:`Wall`."""

    def __init__(self, wall: Wall) -> None:
        self.wall = wall

    def time(self) -> float:
        return self.wall.t

    def monotonic(self) -> float:
        return self.wall.t

    def random_bytes(self, n: int) -> bytes:
        return bytes(n)

    def new_id(self, prefix: str = "") -> str:
        return f"{prefix}000000000000"


def _run(wall: Wall, seconds: float, mark: FleetClock | None, *timers: Every) -> list[int]:
    """Move ``wall`` on by ``seconds`` in steps of :data:`STEP`, marking ``mark`` with a
    simulation running :data:`FAST` times faster; how often each timer held."""
    fired = [0] * len(timers)
    sim = 0.0
    for _ in range(round(seconds / STEP)):
        if mark is not None:
            mark.mark(sim)
        for i, timer in enumerate(timers):
            fired[i] += timer()
        wall.t += STEP
        sim += FAST * STEP
    return fired


def test_a_period_of_the_simulation_fires_five_times_as_often_per_wall_second_as_a_wall_period() -> None:
    wall = Wall()
    fleet = FleetClock(wall)
    sim_timer, wall_timer = Every(2.0), Every(2.0, wall=True)
    sim_timer.bind(fleet, wall)
    wall_timer.bind(fleet, wall)
    _run(wall, 1.0, fleet)  # the first marks: the pace is known
    sim_fired, wall_fired = _run(wall, 20.0, fleet, sim_timer, wall_timer)
    assert wall_fired == 10  # at once, then every 2 wall s
    assert sim_fired == 50  # 100 s of the simulation in 20 wall s
    assert sim_fired == FAST * wall_fired
    assert sim_timer.wall_left() == pytest.approx(sim_timer.left() / FAST)
    assert wall_timer.wall_left() == wall_timer.left()


def test_without_marks_the_clock_runs_at_the_wall_clock_s_pace() -> None:
    wall = Wall()
    fleet = FleetClock(wall)
    timer = Every(2.0)
    timer.bind(fleet, wall)
    assert _run(wall, 20.0, None, timer) == [10]
    assert timer.wall_left() == timer.left()


def test_once_the_marks_stop_the_clock_runs_at_the_wall_clock_s_pace_again() -> None:
    wall = Wall()
    fleet = FleetClock(wall)
    _run(wall, 1.0, fleet)
    assert fleet.fresh() and fleet.pace == pytest.approx(FAST)
    t0 = fleet()  # STEP wall s after the last mark
    wall.t += 10.0  # ag_ex gone: 10 wall s more without a mark
    assert not fleet.fresh()
    assert fleet() - t0 == pytest.approx(FAST * (STALE_S - STEP) + (10.0 + STEP - STALE_S))
    assert fleet.wall_seconds(2.0) == 2.0


def test_the_clock_never_goes_back() -> None:
    wall = Wall()
    fleet = FleetClock(wall)
    _run(wall, 1.0, fleet)
    before = fleet()
    fleet.mark(0.0)  # a world started again: its time starts over
    assert fleet() >= before
    wall.t += 0.1
    fleet.mark(0.5)
    assert fleet() == pytest.approx(before + 0.5)
    wall.t += 0.5  # at 5x the clock reads 2.5 s on; the simulation then slowed down
    ahead = fleet()
    assert ahead == pytest.approx(before + 3.0)
    fleet.mark(1.0)
    assert fleet() == ahead  # held until the simulation catches up


def test_the_simulation_time_travels_as_eight_bytes_and_bad_payloads_are_refused() -> None:
    assert decode_sim_time(encode_sim_time(12.5)) == 12.5
    for bad in (b"", b"1234567", encode_sim_time(float("nan")), encode_sim_time(float("inf"))):
        with pytest.raises(ValueError, match="a simulation time is"):
            decode_sim_time(bad)


def test_a_timer_given_a_clock_keeps_it_and_one_cannot_ask_for_both() -> None:
    wall, own = Wall(), Wall()
    timer = Every(1.0, clock=own)
    timer.bind(FleetClock(wall), wall)
    assert timer.clock is own and timer.fleet is None
    fleet = FleetClock(wall)
    assert Every(1.0, clock=fleet).fleet is fleet  # a condition on the agent's clock (self.fleet_clock)
    with pytest.raises(ValueError, match="not both"):
        Every(1.0, clock=own, wall=True)


class Watcher(Agent):
    """Acts every 2 s on the agent's clock, and every 2 s of wall time."""

    name = "a_i"

    def __init__(self, bus: MemoryBus, wall: Wall) -> None:
        self.on_sim = 0
        self.on_wall = 0
        transport = bus.transport()
        transport.sources = Sources(wall)  # type: ignore[attr-defined]
        super().__init__(transport, SPEC)

    def build_fsm(self) -> FSM:
        return FSM([periodic("watch", 2.0, self._sim_tick, serve=self._wall_tick)])

    def setup(self) -> None:
        self.every_wall = Every(2.0, clock=self.sources.monotonic)

    def _sim_tick(self) -> None:
        self.on_sim += 1

    def _wall_tick(self) -> None:
        self.on_wall += bool(self.every_wall())


def _drive(bus: MemoryBus, wall: Wall, agent: Watcher, seconds: float) -> None:
    actions = agent.engine._elementary_actions()
    sim = 0.0
    for _ in range(round(seconds / STEP)):
        bus.publish(keys.SIM_CLOCK, encode_sim_time(sim))  # as ag_ex does at its state rate
        next(actions)
        wall.t += STEP
        sim += FAST * STEP
    actions.close()


def test_an_agent_s_periodic_behaviour_follows_the_simulation_time_ag_ex_publishes() -> None:
    bus, wall = MemoryBus(), Wall()
    agent = Watcher(bus, wall)
    agent.setup()
    agent.engine.bind()
    _drive(bus, wall, agent, 20.0)
    assert agent.on_wall == 10
    assert agent.on_sim == pytest.approx(FAST * 10, abs=1)  # the first mark's pace is the wall's


class Quick(Agent):
    """Acts every 0.25 s on the agent's clock: less than its sampling period in wall time too."""

    name = "a_i"

    def __init__(self, bus: MemoryBus, wall: Wall) -> None:
        transport = bus.transport()
        transport.sources = Sources(wall)  # type: ignore[attr-defined]
        super().__init__(transport, SPEC)

    def build_fsm(self) -> FSM:
        return FSM([periodic("tick", 0.25, lambda: None)])


def test_the_agent_blocks_until_the_next_period_is_due_in_wall_seconds() -> None:
    bus, wall = MemoryBus(), Wall()
    agent = Quick(bus, wall)
    agent.engine.bind()
    for sim in (0.0, FAST * STEP):  # two marks: the pace is FAST
        bus.publish(keys.SIM_CLOCK, encode_sim_time(sim))
        wall.t += STEP
    bus.publish(keys.SIM_CLOCK, encode_sim_time(2 * FAST * STEP))
    actions = agent.engine._elementary_actions()
    assert next(actions) == pytest.approx(0.25 / FAST)  # acted; 0.25 s of the clock is 0.05 wall s
    actions.close()


def test_in_real_time_the_agent_does_not_listen_and_keeps_wall_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROCO_REALTIME", "1")
    bus, wall = MemoryBus(), Wall()
    agent = Watcher(bus, wall)
    agent.setup()
    agent.engine.bind()
    _drive(bus, wall, agent, 20.0)
    assert agent.on_sim == agent.on_wall == 10


def test_ag_ex_publishes_the_simulation_time_with_its_state_and_an_agent_s_clock_follows() -> None:
    from services.agents.executor.agent import ExecutorAgent
    from velma.executor.state import RobotSnapshot

    class Fake:
        sim_time = 3.0

        def snapshot(self) -> RobotSnapshot:
            return RobotSnapshot(sim_time=self.sim_time, joints={}, grip={}, held={}, held_object={})

    fake = Fake()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Fake:
            return fake

    bus, wall = MemoryBus(), Wall()
    heard: list[float] = []
    bus.subscribe(keys.SIM_CLOCK, lambda _k, p: heard.append(decode_sim_time(p)))
    watcher = Quick(bus, wall)
    watcher.engine.bind()
    ex = Ex(bus.transport())
    for sim in (3.0, 3.25):  # 0.25 s of the simulation in 0.05 wall s
        fake.sim_time = sim
        ex._publish_state()
        ex.engine.dispatch()
        wall.t += STEP
    assert heard == [3.0, 3.25]
    assert watcher.engine.fleet_clock.pace == pytest.approx(FAST)
