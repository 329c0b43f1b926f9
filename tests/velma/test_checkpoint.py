"""Checkpoints of the simulated world (velma/executor/checkpoint.py): a restored world continues
exactly as the original, a held jar stays held when the loop comes back up holding position,
a checkpoint of another model or scene is refused, ROCO_EX_FRESH deletes it, one loop per
directory, and the loop process writes its final checkpoint when it stops."""

from __future__ import annotations

import queue
from pathlib import Path

import msgspec
import numpy as np
import pytest

from shared.fipa_codec.languages.l_ex import CommandResult, Wait
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.grasp import grasp_the_jar, left_jar_lift, run_command
from velma.executor import checkpoint as ck
from velma.executor.handoff import LatestValue
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


def test_the_directory_restores_refuses_and_starts_fresh(tmp_path: Path) -> None:
    d = tmp_path / "ag_ex_state"
    rt = Runtime(n_particles=0)
    loop: ControlLoop[int] = ControlLoop(rt)
    keeper, report = ck.LoopCheckpoints.open(d, rt, loop, block="", fresh=False)
    assert keeper is not None and not report.restored and report.text.startswith("no checkpoint at")
    assert run_command(loop, Wait(duration=0.5)).ok  # type: ignore[union-attr]
    assert keeper.close(loop.holding) is None  # the final checkpoint
    assert (d / ck.FILE_NAME).exists()
    saved_time = rt.time

    back = Runtime(n_particles=0)
    again: ControlLoop[int] = ControlLoop(back)
    keeper, report = ck.LoopCheckpoints.open(d, back, again, block="", fresh=False)
    assert keeper is not None and report.restored and report.sim_time == saved_time
    assert report.text.startswith(f"restored world from checkpoint {d / ck.FILE_NAME} (sim time 0.5")
    assert back.time == saved_time and again.holding == ck.RESTART_WHY
    keeper.close(again.holding)

    other = Runtime(n_particles=1)  # another scene: refused, kept aside, initial scene
    keeper, report = ck.LoopCheckpoints.open(d, other, ControlLoop(other), block="", fresh=False)
    assert keeper is not None and report.refused and not report.restored and report.saving
    assert "made for another model or scene" in report.text and other.time == 0.0
    assert (d / (ck.FILE_NAME + ck.REFUSED_SUFFIX)).exists() and not (d / ck.FILE_NAME).exists()
    keeper.close(None)

    fresh = Runtime(n_particles=1)
    keeper, report = ck.LoopCheckpoints.open(d, fresh, ControlLoop(fresh), block="", fresh=True)
    assert keeper is not None and report.text.startswith("ROCO_EX_FRESH=1: checkpoint")
    assert "deleted" in report.text and not (d / ck.FILE_NAME).exists() and fresh.time == 0.0
    keeper.close(None)


def test_one_loop_per_directory(tmp_path: Path) -> None:
    first = ck.DirLock(tmp_path)
    assert first.acquire(0.0)
    second = ck.DirLock(tmp_path)
    assert not second.acquire(0.1)
    assert first.holder().isdigit()
    first.release()
    assert second.acquire(0.0)
    second.release()


def test_where_checkpoints_live() -> None:
    assert ck.checkpoint_dir({}) is None
    assert ck.checkpoint_dir({"ROCO_RUN_DIR": "/r"}) == Path("/r/ag_ex_state")
    assert ck.checkpoint_dir({"ROCO_RUN_DIR": "/r", "ROCO_EX_STATE": "/s"}) == Path("/s")
    assert ck.checkpoint_dir({"ROCO_EX_STATE": "", "ROCO_RUN_DIR": ""}) is None
    assert ck.fresh_start({"ROCO_EX_FRESH": "1"}) and not ck.fresh_start({"ROCO_EX_FRESH": "0"})


def test_the_writer_writes_new_checkpoints_only(tmp_path: Path) -> None:
    block = LatestValue.create(4096)
    try:
        writer = ck.CheckpointWriter(block, tmp_path / ck.FILE_NAME)
        writer.flush()
        assert writer.writes == 0 and not (tmp_path / ck.FILE_NAME).exists()
        block.write(b"one")
        writer.flush()
        writer.flush()
        assert writer.writes == 1 and (tmp_path / ck.FILE_NAME).read_bytes() == b"one"
        block.write(b"two")
        writer.flush()
        assert writer.writes == 2 and (tmp_path / ck.FILE_NAME).read_bytes() == b"two"
        assert [p.name for p in tmp_path.iterdir()] == [ck.FILE_NAME]  # no temporary left
    finally:
        block.close()
        block.unlink()


def test_the_loop_process_restores_what_it_left(tmp_path: Path) -> None:
    """ExecutorProcess: a stop writes the final checkpoint; the next start restores it and
    holds; ``fresh`` starts from the initial scene."""
    from velma.executor import ExecutorProcess

    first = ExecutorProcess(realtime=False, checkpoint_dir=tmp_path)
    first.start()
    try:
        assert first.restore_report is not None and not first.restore_report.restored
        done: queue.SimpleQueue[Result] = queue.SimpleQueue()
        first.submit(Wait(duration=1.5), done.put)
        assert done.get(timeout=60).ok  # type: ignore[union-attr]
    finally:
        first.stop()
    left = ck.decode((tmp_path / ck.FILE_NAME).read_bytes(), ck.fingerprint(Runtime().model))
    assert left.sim_time >= 1.5

    second = ExecutorProcess(realtime=False, checkpoint_dir=tmp_path)
    second.start()
    try:
        report = second.restore_report
        assert report is not None and report.restored and report.sim_time == left.sim_time
        assert report.age is not None and 0.0 <= report.age < 60.0
        snap = second.snapshot()
        assert snap is not None and snap.sim_time >= left.sim_time and snap.holding == ck.RESTART_WHY
    finally:
        second.stop()

    third = ExecutorProcess(realtime=False, checkpoint_dir=tmp_path, fresh=True)
    third.start()
    try:
        report = third.restore_report
        assert report is not None and not report.restored and "deleted" in report.text
        snap = third.snapshot()
        assert snap is not None and snap.sim_time < left.sim_time and snap.holding is None
    finally:
        third.stop()
