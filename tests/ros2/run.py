"""A small run folder for the ROS 2 export tests, written by roco's own writers: traffic by the
recorder's TrafficWriter, robot state by ag_ex's viewer hook (services/viewer/robot.py), head
camera frames as services/viewer/camera.py logs them (a synthetic image: no rendering), all
merged into ``recording.rrd`` as a run merges them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from services.recorder.recorder import TrafficWriter
from services.runtime.run_folder import RunInfo, write_run_info
from services.viewer import camera, hooks
from services.viewer.robot import SIM, WALL
from shared.fipa_codec.languages.common import Pose
from tests.support.rerun_run import rerun_run_dir
from tests.viewer.test_recording import snapshot, synthetic_traffic

T0 = 1_790_000_000.0
"""When the synthetic traffic begins (POSIX s; tests/viewer/test_recording.py)."""
SNAPSHOTS = (0.0, 0.1, 0.2, 0.3)
"""Robot times (s) of the snapshots; snapshot k is logged at wall time T0 + k."""
FRAMES = (0.15, 0.25)
"""Robot times (s) of the two camera frames."""
FOCAL = 200.0
WIDTH, HEIGHT = 64, 48


def camera_frame(k: int) -> np.ndarray:
    """A synthetic image (HEIGHT × WIDTH × 3, uint8): a gradient that differs per frame."""
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH]
    return np.stack([x * 4, y * 5, np.full_like(x, 60 * k)], axis=-1).astype(np.uint8)


def write_run(folder: Path, monkeypatch: pytest.MonkeyPatch, *, with_camera: bool = True) -> Path:
    """``folder`` made a run folder: run.json, the synthetic traffic and a recording with
    four snapshots and (``with_camera``) two camera frames."""
    run_dir = rerun_run_dir(folder, monkeypatch)
    write_run_info(run_dir, RunInfo(command="pour the jar into the bowl", started=T0 - 1.0))
    robot_side = hooks.robot_hook("ag_ex", run_dir)
    traffic_side = hooks.traffic_hook("recorder", run_dir)
    assert robot_side is not None and traffic_side is not None
    writer = TrafficWriter(run_dir)
    for t, key, payload in synthetic_traffic():
        traffic_side.communicate(writer.write(t, key, payload), payload)
    writer.close()
    for k, t in enumerate(SNAPSHOTS):
        grip = Pose(position=(0.6, 0.2, 0.9 + t))
        robot_side.logger.snapshot(snapshot(t, grip, held="jar" if k else None), wall=T0 + k)
    if with_camera:
        stream = robot_side.recording.stream
        stream.log(
            camera.ENTITY,
            rr.Pinhole(focal_length=FOCAL, width=WIDTH, height=HEIGHT, camera_xyz=rr.ViewCoordinates.RUB),
            static=True,
        )
        rotation = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # looking along +x
        for k, t in enumerate(FRAMES):
            stream.set_time(WALL, timestamp=T0 + 1.5 + k)
            stream.set_time(SIM, duration=t)
            encoded = rr.Image(camera_frame(k)).compress(jpeg_quality=95)
            stream.log(camera.ENTITY, rr.Transform3D(translation=(0.1, 0.0, 1.5), mat3x3=rotation), encoded)
    robot_side.close()
    merged = traffic_side.finish(wait=0.0)
    assert merged is not None
    return run_dir
