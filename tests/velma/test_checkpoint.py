"""Checkpoints of the simulated world (velma/executor/checkpoint.py): a restored world continues
exactly as the original, a held jar stays held when the loop comes back up holding position,
and a checkpoint of another model or scene is refused."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.grasp import grasp_the_jar, left_jar_lift
from velma.executor import checkpoint as ck
from velma.executor.loop import ControlLoop
from velma.executor.runtime import Runtime

Result = CommandResult | Observation


def _holding_the_jar() -> tuple[Runtime, ControlLoop[int]]:
    """The left hand has grasped the jar and is lifting it (the lift still runs)."""
    rt = Runtime()
    rt.observe_by_camera = False  # the ground truth's poses: this test is about checkpoints
    loop: ControlLoop[int] = ControlLoop(rt)
    poses = grasp_the_jar(loop)
    loop.submit(1, left_jar_lift(poses))
    for _ in range(1000):  # mid-lift: the arm moves, the jar is off the shelf
        assert loop.cycle() is None
    return rt, loop


@pytest.fixture(scope="module")
def lifted() -> tuple[Runtime, ControlLoop[int], bytes, np.ndarray]:
    """The world holding the jar, its checkpoint and the jar's position then."""
    rt, loop = _holding_the_jar()
    jar = rt.data.xpos[rt.model.body("jar").id].copy()
    return rt, loop, ck.Capture(rt).take(loop.holding), jar


def test_a_restored_world_continues_exactly_as_the_original(
    lifted: tuple[Runtime, ControlLoop[int], bytes, np.ndarray],
) -> None:
    rt, loop, raw, _ = lifted
    jar = rt.model.body("jar").id
    assert rt.held["left"] == jar and rt.ctrl.arm["left"].mode == "cart"
    copy = Runtime()
    ckpt = ck.decode(raw, ck.fingerprint(copy.model))
    assert ckpt.held == {"right": None, "left": "jar"} and ckpt.sim_time == rt.time
    ck.apply(copy, ckpt)
    assert copy.time == rt.time
    assert np.array_equal(copy.data.qpos, rt.data.qpos) and np.array_equal(copy.data.qvel, rt.data.qvel)
    assert copy.held == rt.held and copy.cycles == rt.cycles
    for side in ("right", "left"):
        a, b = copy.hands.set[side], rt.hands.set[side]
        assert np.array_equal(a.proximal, b.proximal) and np.array_equal(a.broken, b.broken)
        assert copy.ctrl.arm[side].mode == rt.ctrl.arm[side].mode
        assert np.allclose(copy.ctrl.arm[side].pose.homogeneous, rt.ctrl.arm[side].pose.homogeneous)
    # the same setpoints from here on (the original's lift is frozen where it is): both worlds
    # step alike, contact-rich content and all
    loop.pending()
    for _ in range(300):
        rt.cycle()
        copy.cycle()
    assert np.max(np.abs(copy.data.qpos - rt.data.qpos)) < 1e-9
    assert np.max(np.abs(copy.data.qvel - rt.data.qvel)) < 1e-6


def test_the_loop_comes_back_holding_position_and_the_jar(
    lifted: tuple[Runtime, ControlLoop[int], bytes, np.ndarray],
) -> None:
    _, _, raw, jar_then = lifted
    back = Runtime()
    again: ControlLoop[int] = ControlLoop(back)
    ckpt = ck.decode(raw, ck.fingerprint(back.model))
    ck.apply(back, ckpt)
    ck.resume(again, ckpt)
    assert again.holding == ck.RESTART_WHY
    q0 = back.q().copy()
    for _ in range(1500):
        assert again.cycle() is None
    jar = back.model.body("jar").id
    assert back.held["left"] == jar and not back.hold_lost("left")
    assert np.linalg.norm(back.data.xpos[jar] - jar_then) < 0.005  # held where it was, not dropped
    assert back.ctrl.arm["left"].mode == "cart"  # at its restored setpoint, no longer moving
    assert not np.any(back.ctrl.arm["left"].twist)
    for side in ("right", "left"):
        sl = back.ctrl.arm_slice[side]
        assert np.max(np.abs(back.q()[sl] - q0[sl])) < 0.02


def test_safe_mode_stays_safe_mode_across_a_restore() -> None:
    rt = Runtime(n_particles=0)
    loop: ControlLoop[int] = ControlLoop(rt)
    loop.safe("operator")
    raw = ck.Capture(rt).take(loop.holding)
    back = Runtime(n_particles=0)
    again: ControlLoop[int] = ControlLoop(back)
    ckpt = ck.decode(raw, ck.fingerprint(back.model))
    ck.apply(back, ckpt)
    ck.resume(again, ckpt)
    assert again.holding == "safe mode: operator"
    assert {back.ctrl.arm[s].mode for s in ("right", "left")} == {"safe"}


def test_a_checkpoint_of_another_model_or_scene_is_refused(
    lifted: tuple[Runtime, ControlLoop[int], bytes, np.ndarray],
) -> None:
    _, _, raw, _ = lifted
    other_seed = ck.fingerprint(Runtime(seed=1).model)  # the content jittered differently
    with pytest.raises(ck.CheckpointError, match=r"another model or scene .*model_sha256"):
        ck.decode(raw, other_seed)
    fewer = ck.fingerprint(Runtime(n_particles=12).model)
    with pytest.raises(ck.CheckpointError, match="nq 108 ≠ 90"):
        ck.decode(raw, fewer)
    with pytest.raises(ck.CheckpointError, match="unreadable"):
        ck.decode(b"\xc1 not msgpack", fewer)
    wrong_format = msgspec.msgpack.encode(
        msgspec.structs.replace(msgspec.msgpack.decode(raw, type=ck.Checkpoint), format="other/9")
    )
    here = Runtime()
    with pytest.raises(ck.CheckpointError, match="format 'other/9'"):
        ck.decode(wrong_format, ck.fingerprint(here.model))
    ckpt = msgspec.msgpack.decode(raw, type=ck.Checkpoint)
    broken = np.frombuffer(ckpt.controller, dtype=np.float64).copy()
    broken[-1] = np.nan  # the cycle count
    bad = msgspec.structs.replace(ckpt, controller=broken.tobytes())
    time_before = here.time
    with pytest.raises(ck.CheckpointError, match=r"non-finite controller state \(cycles\)"):
        ck.apply(here, ck.decode(msgspec.msgpack.encode(bad), ck.fingerprint(here.model)))
    assert here.time == time_before  # refused before anything was changed
