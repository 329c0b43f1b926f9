"""ag_ex's loop as the controller of a world process (velma/executor/world_link.py): it grasps
and lifts the jar through the robot link alone; killed mid-lift, the world holds the robot and
the jar where they are, and the loop that starts again attaches, knows the jar is in its hand,
and finishes the lift: the world's time never goes back and the jar never jumps."""

from __future__ import annotations

import json
import os
import queue
import signal
import threading
from pathlib import Path

import msgspec
import numpy as np
import pytest

from services.report.build import TIMING_JSON, _control_timing
from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.grasp import LIFT_M, grasp_the_jar, left_jar_lift, run_command
from tests.support.lines import wait_until
from velma.executor import ExecutorProcess
from velma.executor.loop import ControlLoop
from velma.executor.runtime import Runtime
from velma.executor.state import RobotSnapshot
from velma.model.scene import N_PARTICLES, load_kitchen
from velma.world.link import RobotLink

Result = CommandResult | Observation


def test_the_runtime_attached_to_a_world_grasps_and_a_second_one_finds_the_jar_in_hand(world: str) -> None:
    rt = Runtime(link=RobotLink.attach(world))
    assert rt.world is not None and rt.plant is None
    rt.observe_by_camera = False
    loop: ControlLoop[int] = ControlLoop(rt)
    poses = grasp_the_jar(loop)
    jar = rt.model.body("jar").id
    assert rt.held["left"] == jar
    lifted_from = float(rt.data.xpos[jar][2])
    loop.submit(1, left_jar_lift(poses))
    for _ in range(700):  # mid-lift
        assert loop.cycle() is None
    was_at, was_time = rt.data.xpos[jar].copy(), rt.time
    assert was_at[2] > lifted_from + 0.01  # the jar is off the shelf
    rt.world.link.close()  # the controller ends mid-motion
    del loop, rt

    again = Runtime(link=RobotLink.attach(world))
    assert again.world is not None
    # never rolled back (it may not have stepped since: the world waits LOCKSTEP_WAIT_S for a
    # command before its safety layer holds the robot and the kitchen goes on)
    assert again.time >= was_time
    assert again.held["left"] == jar  # it knows from the hand's state and touch what it holds
    assert np.linalg.norm(again.data.xpos[jar] - was_at) < 0.01  # the safety layer held it there
    loop = ControlLoop(again)
    result = run_command(loop, left_jar_lift(poses))
    assert isinstance(result, CommandResult) and result.ok, result
    assert float(again.data.xpos[jar][2]) == pytest.approx(lifted_from + LIFT_M, abs=0.02)
    again.world.link.close()


def test_a_motion_paused_with_its_controller_goes_on_from_where_it_stopped(world: str) -> None:
    """The controller stops commanding mid-lift (as ag_ex does under SIGSTOP) while the world
    holds the robot and its time runs on: the lift's setpoint goes on from where it was, not
    leaping ahead by the time away and dragging the arm after it."""
    rt = Runtime(link=RobotLink.attach(world))
    assert rt.world is not None
    rt.observe_by_camera = False
    loop: ControlLoop[int] = ControlLoop(rt)
    poses = grasp_the_jar(loop)
    loop.submit(1, left_jar_lift(poses))
    for _ in range(300):  # a fifth of the way up
        assert loop.cycle() is None
    paused_at = rt.time
    watch = RobotLink.attach(world)
    scene = np.zeros(watch.n_scene)

    def world_went_on() -> bool:
        return watch.read_scene(scene) is not None and scene[0] > paused_at + 1.5

    wait_until(world_went_on, 30, "the world's time to run 1.5 s on while the robot is held")
    watch.close()
    lag, result = 0.0, None
    for _ in range(5000):
        result = loop.cycle()
        ahead = rt.ctrl.arm["left"].pose.translation - rt.grip("left").translation
        lag = max(lag, float(np.linalg.norm(ahead)))
        if result is not None:
            break
    assert rt.away_s > 1.0
    # the arm lags its moving setpoint by ≈ 6 mm with or without the pause; a setpoint that
    # leapt to the path's end lags by the rest of the lift (≈ 100 mm)
    assert lag < 0.02, f"the setpoint ran {lag * 1000:.0f} mm ahead of the hand"
    assert result is not None and isinstance(result[1], CommandResult) and result[1].ok, result
    rt.world.link.close()


def test_a_world_takes_a_displacement_once(world: str) -> None:
    rt = Runtime(link=RobotLink.attach(world))
    assert rt.world is not None
    loop: ControlLoop[int] = ControlLoop(rt)
    bowl = rt.model.body("bowl").id
    before = rt.data.xpos[bowl].copy()
    rt.displace("bowl", (0.02, 0.0, 0.0))
    for _ in range(50):
        loop.cycle()
    moved = rt.data.xpos[bowl] - before
    assert moved[0] == pytest.approx(0.02, abs=0.003)  # once: not once per cycle
    with pytest.raises(ValueError, match="not a free body"):
        rt.displace("table", (0.0, 0.0, 0.1))
    rt.world.link.close()


def test_a_controller_of_another_kitchen_is_refused(world: str) -> None:
    link = RobotLink.attach(world)
    with pytest.raises(ValueError, match="coordinates"):
        Runtime(link=link, n_particles=4)  # a kitchen with fewer spheres in the jar
    link.close()


class SceneWatch:
    """Reads the world's scene every few milliseconds in a thread: (time, jar position)."""

    def __init__(self, name: str, jar_qpos: int) -> None:
        self.link = RobotLink.attach(name)
        self.samples: list[tuple[float, np.ndarray]] = []
        self.jar_qpos = jar_qpos
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._watch, daemon=True)
        self.thread.start()

    def _watch(self) -> None:
        scene = np.zeros(self.link.n_scene)
        while not self.stop.wait(0.005):
            if self.link.read_scene(scene) is not None:
                at = 1 + self.jar_qpos
                self.samples.append((float(scene[0]), scene[at : at + 3].copy()))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.link.close()


def _call(ex: ExecutorProcess, command: object) -> Result:
    done: queue.SimpleQueue[Result] = queue.SimpleQueue()
    ex.submit(command, done.put)  # type: ignore[arg-type]
    return done.get(timeout=120)


def _state_after(ex: ExecutorProcess, sim_time: float) -> RobotSnapshot:
    """The loop's first published state 25 ms of simulated time after ``sim_time`` (it
    publishes every 20 cycles)."""
    for _ in range(4000):
        snap = ex.snapshot()
        if snap is not None and snap.sim_time >= sim_time + 0.025:
            return snap
        threading.Event().wait(0.005)
    raise AssertionError(f"no state after {sim_time:.3f} s")


def test_ag_ex_killed_mid_lift_leaves_the_jar_where_it_was_and_the_next_loop_lifts_it(world: str) -> None:
    model = load_kitchen(N_PARTICLES, 0, None)
    jar_qpos = int(model.jnt_qposadr[model.body_jntadr[model.body("jar").id]])
    watch = SceneWatch(world, jar_qpos)
    first = ExecutorProcess(realtime=False, world_link=world, perception="truth", realtime_priority=False)
    first.start()
    try:
        poses = grasp_the_jar(lambda command: _call(first, command))
        grasped = first.snapshot()
        assert grasped is not None
        assert _state_after(first, grasped.sim_time).held_object["left"] == "jar"
        lift: queue.SimpleQueue[Result] = queue.SimpleQueue()
        first.submit(left_jar_lift(poses), lift.put)
        _state_after(first, grasped.sim_time + 0.7)  # mid-lift
        assert first.pid is not None
        os.kill(first.pid, signal.SIGKILL)  # ag_ex's loop dies mid-lift, as under roco chaos
        result = lift.get(timeout=30)
        assert isinstance(result, CommandResult) and not result.ok
    finally:
        first.stop()
    killed_at = len(watch.samples)

    second = ExecutorProcess(realtime=False, world_link=world, perception="truth", realtime_priority=False)
    second.start()
    try:
        snap = second.snapshot()
        assert snap is not None and snap.held_object["left"] == "jar"  # it knows what its hand holds
        result = _call(second, left_jar_lift(poses))
        assert isinstance(result, CommandResult) and result.ok, result
    finally:
        second.stop()
        watch.close()
    times = np.array([t for t, _ in watch.samples])
    jar = np.array([p for _, p in watch.samples])
    assert 0 < killed_at < len(times)
    assert np.all(np.diff(times) >= 0.0)  # the world's time never goes back
    steps = np.linalg.norm(np.diff(jar, axis=0), axis=1)
    assert steps.max() < 0.01  # the jar never jumps: no rollback, no drop
    assert jar[-1][2] - jar[0][2] == pytest.approx(LIFT_M, abs=0.02)


def test_the_world_s_timing_reaches_the_loop_s_figures_and_the_run_s_report(
    world: str, tmp_path: Path
) -> None:
    ex = ExecutorProcess(realtime=False, world_link=world, perception="truth", realtime_priority=False)
    ex.start()
    try:
        first = ex.timing().world
        snap = _state_after(ex, _state_after(ex, 0.0).sim_time + 0.2)
        timing = ex.timing()
    finally:
        ex.stop()
    assert first is not None and timing.world is not None
    w = timing.world
    assert w.pacing == "fast"
    assert w.cycles > first.cycles and w.cycles >= round(snap.sim_time * 1000) - 100  # copied every 100
    assert w.held > 0  # the safety layer held the robot until the loop attached
    assert w.stale == 0 and w.stale_by_age == (0, 0, 0, 0)  # in lockstep every command is the newest
    # as ag_ex writes it into the run folder (services/agents/executor/agent.py) and the report reads it
    (tmp_path / TIMING_JSON).write_text(json.dumps(msgspec.to_builtins(timing), indent=1))
    notes: list[str] = []
    assert _control_timing(tmp_path, notes) == timing and not notes
