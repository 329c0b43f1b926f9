"""ag_ex's head camera in the Rerun recording (services/viewer/camera.py): frames rendered off
the loop from the whole simulation state, logged as JPEG images with the camera's pose and a
pinhole; frames are skipped when nothing changed; no EGL means one warning and no images;
ag_ex starts the camera with Rerun on and stops it before its executor."""

from __future__ import annotations

import io
import logging
import os
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image as PILImage
from rerun.chunk import RrdReader

from services.agents.executor.agent import ExecutorAgent
from services.runtime.memory_transport import MemoryBus
from services.viewer import camera, hooks, recording, robot
from shared.fipa_codec.languages.common import Pose
from tests.support.machine import needs_gl
from tests.support.rerun_run import rerun_run_dir
from tests.viewer.test_recording import rows
from velma.executor.loop_wire import WorldState
from velma.executor.state import RobotSnapshot
from velma.executor.timing import TimingStats

RUN = "20261121-130000-camera"
ENTITY = f"/{camera.ENTITY}"


@pytest.fixture
def run_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    return rerun_run_dir(tmp_path / RUN, monkeypatch, "ROCO_RERUN_CAMERA")


@pytest.fixture(scope="module")
def kitchen_qpos() -> np.ndarray:
    from velma.model.scene import initial_state, load_kitchen

    model = load_kitchen()
    return initial_state(model).qpos.copy()


class Source:
    """A world-state source: the kitchen's initial state, its simulation time advancing by
    0.1 s per call unless ``frozen``; ``calls`` is set once it was asked ``n`` times."""

    def __init__(self, qpos: np.ndarray, *, frozen: bool = False, n: int = 5) -> None:
        self.qpos = qpos
        self.frozen = frozen
        self.count = 0
        self.n = n
        self.calls = threading.Event()

    def __call__(self) -> WorldState:
        self.count += 1
        if self.count >= self.n:
            self.calls.set()
        return WorldState(sim_time=0.0 if self.frozen else 0.1 * self.count, qpos=self.qpos)


def camera_columns(path: Path) -> tuple[list[bytes], list[str], list[list[float]]]:
    """JPEG blobs, media types and camera translations logged at the camera entity."""
    blobs: list[bytes] = []
    media: list[str] = []
    where: list[list[float]] = []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != ENTITY or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith("EncodedImage:blob"):
                blobs += [bytes(v[0]) for v in batch.column(name).to_pylist()]
            elif name.endswith("EncodedImage:media_type"):
                media += [v[0] for v in batch.column(name).to_pylist()]
            elif name.endswith("Transform3D:translation"):
                where += [v[0] for v in batch.column(name).to_pylist()]
    return blobs, media, where


@needs_gl
def test_frames_are_logged_with_pose_and_pinhole(run_dir: Path, kitchen_qpos: np.ndarray) -> None:
    hook = hooks.robot_hook("ag_ex", run_dir)
    assert hook is not None
    source = Source(kitchen_qpos)
    hook.camera = camera.HeadCamera(hook.recording, source, period=0.05)
    hook.camera.start()
    assert hook.camera.wait_frames(3, timeout=120), hook.camera.failed
    thread_id = hook.camera._thread.native_id
    assert thread_id is not None and os.getpriority(os.PRIO_PROCESS, thread_id) == camera.NICE
    hook.close()
    assert not hook.camera.running
    frames = hook.camera.frames
    merged = recording.merge_parts(run_dir)
    assert merged is not None
    assert rows(merged)[ENTITY] == frames
    blobs, media, where = camera_columns(merged)
    assert len(blobs) == frames and set(media) == {"image/jpeg"}
    image = np.asarray(PILImage.open(io.BytesIO(blobs[0])))
    assert image.shape == (camera.HEIGHT, camera.WIDTH, 3)
    assert image.std() > 10  # a scene, not a blank frame
    # the head camera sits above the torso, 1.3–1.6 m up, looking ahead (+x)
    x, y, z = where[0]
    assert 0.0 < x < 0.4 and abs(y) < 0.1 and 1.3 < z < 1.6
    static = [c for c in RrdReader(merged).stream() if c.is_static and c.entity_path == ENTITY]
    names = [n for c in static for n in c.to_record_batch().schema.names]
    assert any(n.endswith("Pinhole:image_from_camera") for n in names)


@needs_gl
def test_unchanged_state_is_not_rendered_again(run_dir: Path, kitchen_qpos: np.ndarray) -> None:
    rec = recording.start("ag_ex", run_dir=run_dir)
    assert rec is not None
    source = Source(kitchen_qpos, frozen=True, n=6)
    cam = camera.HeadCamera(rec, source, period=0.02)
    cam.start()
    assert source.calls.wait(120)
    cam.stop()
    rec.close()
    assert cam.failed is None
    assert cam.frames == 1 and cam.skipped >= source.n - 1


def test_no_egl_means_one_warning_and_no_images(
    run_dir: Path, kitchen_qpos: np.ndarray, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    import velma.render

    def no_gl(self: Any, qpos: np.ndarray) -> Any:
        raise RuntimeError("Cannot initialize a EGL device display")

    monkeypatch.setattr(velma.render.SceneCamera, "render", no_gl)
    hook = hooks.robot_hook("ag_ex", run_dir)
    assert hook is not None
    with caplog.at_level(logging.WARNING, logger=camera.__name__):
        hook.start_camera(Source(kitchen_qpos))
        assert hook.camera is not None
        assert not hook.camera.wait_frames(1, timeout=120)  # the thread ended without a frame
        hook.close()
    assert "EGL" in (hook.camera.failed or "")
    warnings = [r for r in caplog.records if r.name == camera.__name__]
    assert len(warnings) == 1 and "without images" in warnings[0].getMessage()
    assert not hook.failed  # the rest of the robot's logging goes on


class CameraFake:
    """An executor with a whole-state source, as ExecutorProcess(world_state=True) has; its
    ``stop`` notes whether the camera still ran."""

    world_state = True
    seed = 0
    pose_seed = None

    def __init__(self, qpos: np.ndarray) -> None:
        self.source = Source(qpos)
        self.camera_running_at_stop: bool | None = None
        self.agent: ExecutorAgent | None = None

    def start(self) -> None: ...

    def stop(self) -> None:
        cam = self.agent.rerun.camera if self.agent and self.agent.rerun else None
        self.camera_running_at_stop = cam is not None and cam.running

    def submit(self, command: Any, on_done: Any) -> None: ...

    def world(self) -> WorldState:
        return self.source()

    def snapshot(self) -> RobotSnapshot:
        t = 0.1 * self.source.count
        return RobotSnapshot(
            sim_time=t,
            joints={"torso_0_joint": 0.0},
            grip={"right": Pose(position=(0.5, 0.0, 1.0))},
            held={"right": False},
            held_object={"right": None},
            timing=TimingStats(
                pacing="fast",
                cycles=1000 * self.source.count,
                window=1000,
                compute_p50_us=380.0,
                compute_p99_us=700.0,
                compute_max_us=1500.0,
                lateness_p50_us=0.0,
                lateness_p99_us=0.0,
                lateness_max_us=0.0,
                overruns=2,
                overrun_share=0.002,
                max_consecutive_overruns=1,
                sim_time=t,
            ),
        )


@needs_gl
def test_ag_ex_starts_the_camera_and_stops_it_before_the_executor(
    run_dir: Path, kitchen_qpos: np.ndarray
) -> None:
    fake = CameraFake(kitchen_qpos)

    set_up = threading.Event()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            return fake

        def setup(self) -> None:
            super().setup()
            set_up.set()

    agent = Ex(MemoryBus().transport())
    fake.agent = agent
    assert agent.rerun is not None
    agent.engine.bind()
    thread = threading.Thread(target=agent.engine.run, daemon=True)
    thread.start()
    try:
        assert set_up.wait(60)
        assert agent.rerun.camera is not None
        assert agent.rerun.camera.wait_frames(2, timeout=120), agent.rerun.camera.failed
    finally:
        agent.engine.stop()
        thread.join(10)
        agent.close()
    assert fake.camera_running_at_stop is False
    merged = recording.merge_parts(run_dir)
    assert merged is not None
    counts = rows(merged)
    assert counts[ENTITY] >= 2
    assert counts[f"/{robot.TIMING}/compute/p99"] >= 1  # the snapshots carried the timing


def test_camera_off_when_asked_or_rerun_off(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROCO_RERUN", "1")
    monkeypatch.setenv("ROCO_RERUN_CAMERA", "0")
    assert not hooks.camera_wanted()
    monkeypatch.delenv("ROCO_RERUN_CAMERA")
    assert hooks.camera_wanted()
    monkeypatch.delenv("ROCO_RERUN")
    assert not hooks.camera_wanted()


@needs_gl
def test_the_loop_publishes_its_whole_state_only_when_asked(tmp_path: Path, kitchen_qpos: np.ndarray) -> None:
    """ExecutorProcess(world_state=True): the camera renders what the loop process simulates."""
    from velma.executor import ExecutorProcess

    plain = ExecutorProcess(realtime=False)
    plain.start()
    try:
        assert plain.world() is None
    finally:
        plain.stop()
    ex = ExecutorProcess(realtime=False, world_state=True)
    ex.start()
    rec = recording.Recording("ag_ex", tmp_path, "world")
    cam = camera.HeadCamera(rec, ex.world, period=0.05)
    try:
        cam.start()
        assert cam.wait_frames(2, timeout=120), cam.failed
        cam.stop()
        state = ex.world()
        assert state is not None and state.sim_time > 0.0
        assert state.qpos.shape == kitchen_qpos.shape and np.isfinite(state.qpos).all()
    finally:
        cam.stop()
        rec.close()
        ex.stop()
    assert ex.world() is None
