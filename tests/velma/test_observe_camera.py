"""Observe by the head camera: the loop hands off a world capture, the camera's
Observation comes back in order, what is out of view is ``unseen`` while the physics has it."""

from __future__ import annotations

import math
import queue

import pytest

from shared.fipa_codec.languages.l_ex import CommandResult, LookAt, Observe, Wait
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.machine import needs_gl
from velma.executor import Executor
from velma.executor.capture import DEFAULT_PERCEPTION, WorldCapture, perception_mode
from velma.executor.loop import ControlLoop
from velma.executor.observer import POSITION_SIGMA_FLOOR
from velma.executor.runtime import Runtime

Result = CommandResult | Observation


def test_the_loop_captures_the_world_and_renders_nothing() -> None:
    rt = Runtime()
    rt.observe_by_camera = True  # as ExecutorProcess and Executor set it for ROCO_PERCEPTION=camera
    loop: ControlLoop[int] = ControlLoop(rt)
    loop.submit(1, Observe(objects=("jar",)))
    done = loop.cycle()
    assert done is not None and isinstance(done[1], WorldCapture)
    capture = done[1]
    assert capture.objects == ("jar",)
    assert capture.positions().shape == (rt.model.nq,)


def test_perception_mode_is_the_default_unless_one_is_asked(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MUJOCO_GL", "egl")  # a GL library is installed (tests/velma/test_gl.py: none)
    assert perception_mode({}) == DEFAULT_PERCEPTION == perception_mode({"ROCO_PERCEPTION": ""})
    assert perception_mode({"ROCO_PERCEPTION": "camera"}) == "camera"
    assert perception_mode({"ROCO_PERCEPTION": "truth"}) == "truth"
    with pytest.raises(ValueError):
        perception_mode({"ROCO_PERCEPTION": "oracle"})


def _run(ex: Executor, *commands: object) -> list[Result]:
    box: queue.SimpleQueue[Result] = queue.SimpleQueue()
    for c in commands:
        ex.submit(c, box.put)  # type: ignore[arg-type]
    return [box.get(timeout=120) for _ in commands]


@needs_gl
@pytest.mark.requirement("R3.1")
def test_camera_observation_in_order_and_unseen_out_of_view() -> None:
    records: list[dict[str, object]] = []
    ex = Executor(perception="camera", perception_log=records.extend)
    ex.start()
    try:
        # an Observe (≈ 0.2 s of rendering outside the loop) and a Wait that ends in the next
        # cycle: the Wait's result must not overtake the Observation
        first, waited = _run(ex, Observe(), Wait(duration=0.0))
        assert isinstance(first, Observation) and isinstance(waited, CommandResult)
        seen = {o.name: o for o in first.objects}
        assert {"jar", "bowl", "cup"} <= set(seen) and first.unseen == ()
        truth = ex.rt.ground_truth
        for name in ("jar", "bowl", "cup"):
            o = seen[name]
            assert o.position_sigma is not None and o.position_sigma >= POSITION_SIGMA_FLOOR
            assert not o.yaw_observable
        assert first.total_particles == truth.particle_bodies.size
        assert seen["table"].position_sigma is None  # a map fact, not a measurement
        logged = {r["object"]: r for r in records}
        assert set(logged) == {"jar", "bowl", "cup"}
        assert all(isinstance(r["error_mm"], float) and r["error_mm"] < 10.0 for r in logged.values())
        # the head turned to the table: the shelf's objects are out of view, not guessed
        look, hidden = _run(ex, LookAt(point=(0.3, -0.65, 0.75)), Observe(objects=("jar", "bowl")))
        assert isinstance(look, CommandResult) and look.ok, look
        assert isinstance(hidden, Observation)
        assert hidden.unseen == ("jar", "bowl")
        assert hidden.objects == ()
        physics = truth.observe(ex.rt.data, ("jar", "bowl"))  # the physics still has both
        assert [o.name for o in physics.objects] == ["jar", "bowl"]
        # the hands are known from the joints wherever the camera looks: the grip frames the
        # controller's kinematics (Pinocchio) has, within 1 mm
        assert [g.name for g in hidden.grips] == ["left_gripper", "right_gripper"]
        for g in hidden.grips:
            side = g.name.removesuffix("_gripper")
            assert math.dist(g.pose.position, ex.rt.ctrl.grip_pose(side).translation) < 1e-3, side
    finally:
        ex.stop()


def test_truth_mode_is_the_physics() -> None:
    ex = Executor(perception="truth")
    ex.start()
    try:
        (obs,) = _run(ex, Observe(objects=("jar", "nothing")))
        assert isinstance(obs, Observation)
        assert [o.name for o in obs.objects] == ["jar"] and obs.unseen == ("nothing",)
        assert obs.objects[0].position_sigma is None
        assert [g.name for g in obs.grips] == ["left_gripper", "right_gripper"]
    finally:
        ex.stop()
