"""The world process's timing (velma/world/timing.py): late cycles, stalls, schedule resets,
stale commands, holds and waits are counted, and reach the link's counters. The world's cycle
(velma/world/serve.py ``serve``) runs here on a test clock and a stand-in for the physics, so
that every lateness is planted, not waited for."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import numpy.typing as npt
import pytest

from velma.world.layout import COMMAND, MEASURED
from velma.world.link import RobotLink
from velma.world.serve import serve
from velma.world.timing import (
    DT,
    LATE_AFTER_S,
    MAX_BEHIND_S,
    N_AGES,
    N_SLOTS,
    STALL_PERIODS,
    WorldClock,
    WorldTiming,
)

Array = npt.NDArray[np.float64]
STEP_S = 0.0003
"""How long (s, on the test clock) one physics step of the stand-in takes."""


class PlantedClock:
    """A monotonic clock that moves only when the world steps or sleeps."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


class StandIn:
    """The physics, as ``serve`` uses it: each step takes ``STEP_S`` on ``clock``, plus the
    delay ``slow`` plants for that step; ``on_step`` (cycle) plays the controller."""

    scene_size = 0
    holding = False

    def __init__(self, clock: PlantedClock, slow: dict[int, float] | None = None) -> None:
        self.clock, self.slow = clock, slow or {}
        self.k = 0
        self.applied: list[bool] = []
        self.on_step = lambda k: None

    def measure(self, out: Array) -> None:
        out[:] = self.k

    def scene(self, out: Array) -> None:
        pass  # a kitchen of no coordinates

    def apply(self, command: Array | None) -> None:
        self.applied.append(command is not None)

    def step(self) -> None:
        self.clock.now += STEP_S + self.slow.get(self.k, 0.0)
        self.on_step(self.k)
        self.k += 1


@pytest.fixture
def link() -> Iterator[RobotLink]:
    made = RobotLink.create(MEASURED.size, COMMAND.size)
    yield made
    made.close()


def _serve(sim: StandIn, link: RobotLink, clock: PlantedClock, cycles: int, *, realtime: bool) -> WorldTiming:
    ran = serve(
        sim,  # type: ignore[arg-type]
        link,
        realtime=realtime,
        should_stop=lambda: False,
        max_cycles=cycles,
        clock=clock,
        sleep=clock.sleep,
    )
    assert ran == cycles
    return WorldTiming.read(link.counters)


def test_a_schedule_150_ms_behind_counts_one_reset_and_goes_on_from_there(link: RobotLink) -> None:
    clock = PlantedClock()
    sim = StandIn(clock, slow={200: 0.150})  # step 200 takes 150 ms more: cycle 201 starts late
    sim.on_step = lambda k: link.command(k, np.zeros(COMMAND.size))  # a controller on time
    timing = _serve(sim, link, clock, 1000, realtime=True)
    assert timing.pacing == "realtime"
    assert timing.cycles == timing.paced == 1000
    assert timing.resets == 1
    assert timing.late == 1  # cycle 201 only: the cycles after it are due from its start
    assert timing.late_max_us == pytest.approx((0.150 + STEP_S - DT) * 1e6, abs=1.0)
    assert timing.stalls == 1
    assert timing.gap_max_us == pytest.approx((0.150 + STEP_S) * 1e6, abs=1.0)
    assert timing.stale == 0 and timing.held == 1  # cycle 0 has no command to apply


def test_a_cycle_two_periods_late_is_late_but_no_reset(link: RobotLink) -> None:
    clock = PlantedClock()
    sim = StandIn(clock, slow={50: 0.002})
    timing = _serve(sim, link, clock, 100, realtime=True)
    assert (timing.late, timing.resets, timing.stalls) == (1, 0, 0)
    assert timing.late_max_us == pytest.approx((0.002 + STEP_S - DT) * 1e6, abs=1.0)


def test_without_a_planted_delay_nothing_is_late(link: RobotLink) -> None:
    clock = PlantedClock()
    timing = _serve(StandIn(clock), link, clock, 300, realtime=True)
    assert (timing.late, timing.resets, timing.stalls, timing.stale) == (0, 0, 0, 0)
    assert timing.held == 300  # no controller: the safety layer held every step


def test_a_command_whose_cycle_lags_counts_stale_with_its_age(link: RobotLink) -> None:
    clock = PlantedClock()
    sim = StandIn(clock)

    def controller(k: int) -> None:
        # answers state k on time, except that the answers to states 40 … 42 come late: at
        # cycles 41 … 43 the newest command is the one for state 39 (ages 1, 2, 3)
        if not 40 <= k <= 42:
            link.command(k, np.zeros(COMMAND.size))

    sim.on_step = controller
    timing = _serve(sim, link, clock, 100, realtime=True)
    assert timing.stale == 3
    assert timing.stale_worst_age == 3
    assert timing.stale_by_age == (1, 1, 1, 0)
    assert timing.held == 1


def test_a_command_older_than_the_hold_is_not_stale_but_held(link: RobotLink) -> None:
    clock = PlantedClock()
    sim = StandIn(clock)
    sim.on_step = lambda k: link.command(k, np.zeros(COMMAND.size)) if k < 10 else None
    timing = _serve(sim, link, clock, 30, realtime=True)
    # cycles 11 … 14 apply the command for state 9 (ages 1 … 4); from cycle 15 on it is too old
    assert timing.stale_by_age == (1, 1, 1, 1)
    assert timing.held == 1 + (30 - 15)
    assert sim.applied.count(False) == timing.held


def test_lockstep_counts_the_waits_for_the_controller_and_no_lateness(link: RobotLink) -> None:
    clock = PlantedClock()
    sim = StandIn(clock)
    sim.on_step = lambda k: link.command(k, np.zeros(COMMAND.size)) if k % 10 else None

    def wait_command(cycle: int, timeout_s: float, spin_s: float) -> bool:
        clock.now += 0.003  # the controller answers 3 ms later
        link.command(cycle, np.zeros(COMMAND.size))
        return True

    link.wait_command = wait_command  # type: ignore[method-assign]
    timing = _serve(sim, link, clock, 100, realtime=False)
    assert timing.pacing == "fast" and timing.paced == 0
    assert timing.waits == 10  # cycles 1, 11, … 91: the answers to states 0, 10, … 90 come late
    assert timing.wait_max_us == pytest.approx(3000.0)
    assert (timing.late, timing.resets, timing.stale, timing.stalls) == (0, 0, 0, 0)
    assert timing.held == 1
    assert timing.gap_max_us == pytest.approx(STEP_S * 1e6)  # the waits are not the world's gaps


def test_the_clock_counts_each_kind_on_planted_times() -> None:
    counts = WorldClock(realtime=True)
    assert not counts.started(0.0, 0.0)
    assert not counts.started(DT, DT + LATE_AFTER_S)  # early is on time
    assert not counts.started(2 * DT + LATE_AFTER_S + 1e-4, 2 * DT)  # late, no reset
    assert counts.started(1.0, 3 * DT)  # far behind: a reset
    counts.applied(5, 4)
    counts.applied(6, 2)
    counts.applied(7, None)
    fig = counts.figures()
    assert (fig.cycles, fig.late, fig.resets, fig.stalls) == (4, 2, 1, 1)
    assert (fig.stale, fig.stale_worst_age, fig.stale_by_age, fig.held) == (1, 3, (0, 0, 1, 0), 1)
    assert fig.gap_max_us > STALL_PERIODS * DT * 1e6
    assert len(fig.stale_by_age) == N_AGES


def test_holds_between_two_commands_are_told_apart_from_holds_before_and_after() -> None:
    counts = WorldClock(realtime=True)
    for cycle in range(3):  # before a controller attached
        counts.applied(cycle, None)
    counts.applied(3, 2)
    counts.applied(4, None)  # its command came too late, twice
    counts.applied(5, None)
    counts.applied(6, 5)
    for cycle in range(7, 10):  # after it ended
        counts.applied(cycle, None)
    fig = counts.figures()
    assert (fig.held, fig.held_attached) == (8, 2)


def test_the_counts_need_their_slots() -> None:
    with pytest.raises(ValueError, match="slots"):
        WorldClock(np.zeros(N_SLOTS - 1, dtype=np.int64), realtime=True)
    with pytest.raises(ValueError, match="slots"):
        WorldTiming.read(np.zeros(3, dtype=np.int64))


def test_the_world_period_is_the_hardware_s() -> None:
    from velma.world import hardware

    assert DT == hardware.DT
    assert MAX_BEHIND_S > LATE_AFTER_S
