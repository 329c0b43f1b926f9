"""ag_ex's watch (velma/executor/watch.py, ``ExecutorProcess.watch``): frames every period of
robot time, never more than one in flight; the loop's pacer switched at run time and back; the
camera's watch mode (one frame, no content count); frames come through the delivery in order
and stop with ``unwatch``."""

from __future__ import annotations

import itertools
import queue
from collections.abc import Iterator
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pytest

from shared.fipa_codec.languages.l_ex import CommandResult, Observe, Wait
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.machine import needs_gl
from velma.executor import ExecutorProcess
from velma.executor.capture import WorldCapture
from velma.executor.timing import Pacer
from velma.executor.watch import Watcher, check_period


class _State(NamedTuple):
    sim_time: float
    qpos: npt.NDArray[np.float64]


class _World:
    """A world state whose time the test sets."""

    def __init__(self) -> None:
        self.t: float | None = None

    def __call__(self) -> _State | None:
        return None if self.t is None else _State(self.t, np.zeros(3))


@pytest.fixture
def made() -> Iterator[tuple[_World, list[WorldCapture], Watcher]]:
    world, frames = _World(), list[WorldCapture]()
    w = Watcher(world, frames.append, ("bowl",), 0.5, poll_s=3600.0)  # the test steps it
    yield world, frames, w
    w.stop()


def test_a_frame_every_period_of_robot_time(made: tuple[_World, list[WorldCapture], Watcher]) -> None:
    world, frames, w = made
    assert not w.step()  # no state yet
    world.t = 1.0
    assert w.step() and frames[-1].stamp == 1.0 and frames[-1].watch and frames[-1].objects == ("bowl",)
    w.delivered()
    world.t = 1.4
    assert not w.step()  # not due: 0.5 s of robot time after the last
    world.t = 1.5
    assert w.step() and frames[-1].stamp == 1.5
    assert w.frames == 2 and w.skipped == 0


def test_frames_never_queue_up_a_due_one_is_skipped(made: tuple[_World, list[WorldCapture], Watcher]) -> None:
    world, frames, w = made
    world.t = 0.0
    assert w.step()
    world.t = 0.6  # due, but the first is still being observed
    assert not w.step() and w.skipped == 1 and len(frames) == 1
    world.t = 0.8
    assert not w.step()  # the next is due at 1.0 (0.5 after the skipped one)
    w.delivered()
    assert not w.step()
    world.t = 1.0
    assert w.step() and [f.stamp for f in frames] == [0.0, 1.0]


def test_a_watch_period_out_of_range_is_refused() -> None:
    for bad in (0.0, -1.0, float("nan"), float("inf"), 1000.0):
        with pytest.raises(ValueError, match="watch period"):
            check_period(bad)
    assert check_period(0.25) == 0.25


def test_the_pacer_switches_to_a_pace_of_the_simulations_time_and_back() -> None:
    fast = Pacer(0.001, realtime=False, spin=0.0003)
    fast.pace(0.5)
    assert fast.realtime and fast.spin == 0.0
    fast.wait(10.0)  # the pace counts from here
    first = fast.release
    fast.wait(10.003)  # a world that stepped 3 ms in one cycle: released 6 ms of wall time on
    assert fast.release - first == pytest.approx(0.006)
    fast.pace(None)
    assert not fast.realtime and fast.dt == 0.001 and fast.spin == 0.0003
    paced = Pacer(0.001, realtime=True, spin=0.0003)  # real-time pacing is unchanged
    paced.pace(2.0)
    assert paced.realtime and paced.dt == 0.001
    with pytest.raises(ValueError, match="pace"):
        fast.pace(0.0)


@needs_gl
def test_the_executor_watches_in_order_with_results_and_stops() -> None:
    ex = ExecutorProcess(realtime=False, world_state=True, perception="camera", watch_pace=1.0)
    ex.start()
    try:
        frames: queue.SimpleQueue[Observation] = queue.SimpleQueue()
        results: queue.SimpleQueue[CommandResult | Observation] = queue.SimpleQueue()
        ex.watch(("bowl", "jar"), 0.2, frames.put)
        got = [frames.get(timeout=120) for _ in range(3)]
        stamps = [f.stamp for f in got]
        assert stamps == sorted(stamps) and all(b - a >= 0.2 - 1e-9 for a, b in itertools.pairwise(stamps))
        bowl = next(o for o in got[0].objects if o.name == "bowl")
        assert bowl.particles_inside is None and got[0].particles_outside is None  # no count
        assert got[0].grips  # the hands, as an Observe's
        ex.submit(Observe(objects=("bowl",)), results.put)
        look = results.get(timeout=120)
        assert isinstance(look, Observation) and not isinstance(look, CommandResult)
        assert next(o for o in look.objects if o.name == "bowl").particles_inside is not None
        ex.unwatch()
        assert not ex.watching
        while not frames.empty():  # one in flight may still come
            frames.get()
        ex.submit(Wait(duration=0.5), results.put)
        assert results.get(timeout=120).ok  # type: ignore[union-attr]
        assert frames.empty()  # none made after unwatch
    finally:
        ex.stop()


def test_a_watch_without_the_camera_or_the_world_state_says_why() -> None:
    ex = ExecutorProcess(realtime=False, world_state=False, perception="truth")
    with pytest.raises(RuntimeError, match="not started"):
        ex.watch((), 0.5, lambda _obs: None)
    ex.start()
    try:
        with pytest.raises(RuntimeError, match="head camera"):
            ex.watch((), 0.5, lambda _obs: None)
    finally:
        ex.stop()
