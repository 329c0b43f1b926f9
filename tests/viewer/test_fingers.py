"""The BarrettHand's fingers in the Rerun recording (services/viewer/robot.py): the finger
links' frames computed from the snapshot's joint angles are MuJoCo's, and a hand's fingers
are logged again only when they moved."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from services.viewer import hooks, recording, robot
from shared.fipa_codec.languages.common import Pose
from tests.viewer.test_recording import rows
from velma.control.joints import SIDES
from velma.executor.state import RobotSnapshot

RUN = "20261121-150000-fingers"
BODIES = {  # entity below the palm -> MJCF body (after "<side>_")
    "finger_one": "HandFingerOneKnuckleOneLink",
    "finger_one/proximal": "HandFingerOneKnuckleTwoLink",
    "finger_one/proximal/distal": "HandFingerOneKnuckleThreeLink",
    "finger_two": "HandFingerTwoKnuckleOneLink",
    "finger_two/proximal": "HandFingerTwoKnuckleTwoLink",
    "finger_two/proximal/distal": "HandFingerTwoKnuckleThreeLink",
    "finger_three": "HandFingerThreeKnuckleTwoLink",
    "finger_three/distal": "HandFingerThreeKnuckleThreeLink",
}


def test_finger_frames_are_mujocos() -> None:
    from velma.model.scene import initial_state, load_kitchen

    model = load_kitchen()
    data = initial_state(model)
    rng = np.random.default_rng(7)
    angles: dict[str, float] = {}
    for side in SIDES:
        for link in robot.FINGER_LINKS:
            name = f"{side}_{link.joint}"
            angles[name] = float(rng.uniform(0.1, 1.0))
            data.qpos[model.joint(name).qposadr[0]] = angles[name]
    mujoco.mj_kinematics(model, data)
    assert {link.path for link in robot.FINGER_LINKS} == set(BODIES)
    for side in SIDES:
        palm = model.body(f"{side}_HandPalmLink").id
        world = {"": Pose(position=tuple(data.xpos[palm]), orientation=tuple(data.xquat[palm]))}
        for link in robot.FINGER_LINKS:  # parents come first
            parent = link.path.rsplit("/", 1)[0] if "/" in link.path else ""
            pose = robot.compose(world[parent], robot.finger_pose(link, angles[f"{side}_{link.joint}"]))
            world[link.path] = pose
            body = model.body(f"{side}_{BODIES[link.path]}").id
            assert pose.position == pytest.approx(data.xpos[body], abs=1e-12), link.path
            assert abs(np.dot(pose.orientation, data.xquat[body])) == pytest.approx(1.0, abs=1e-12)


def snap(t: float, right: float, left: float) -> RobotSnapshot:
    joints = {
        f"{side}_{link.joint}": a
        for side, a in (("right", right), ("left", left))
        for link in robot.FINGER_LINKS
    }
    return RobotSnapshot(
        sim_time=t,
        joints=joints,
        grip={"right": Pose(position=(0.5, 0.0, 1.0))},
        held={"right": False},
        held_object={"right": None},
    )


def test_fingers_are_logged_when_they_move(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run_dir = tmp_path / RUN
    run_dir.mkdir()
    monkeypatch.setenv("ROCO_RERUN", "1")
    monkeypatch.setenv("ROCO_RUN_DIR", str(run_dir))
    hook = hooks.robot_hook("ag_ex", run_dir)
    assert hook is not None
    hook.snapshot(snap(0.0, 0.0, 0.0))  # both hands: first time
    hook.snapshot(snap(0.05, 0.5 * robot.FINGER_EPS, 0.0))  # too little: nothing
    hook.snapshot(snap(0.10, 0.3, 0.0))  # the right hand closes
    hook.snapshot(snap(0.15, 0.6, 0.0))
    hook.close()
    merged = recording.merge_parts(run_dir)
    assert merged is not None
    counts = rows(merged)
    for path in BODIES:
        assert counts[f"/{robot.LINKS}/right_HandPalmLink/{path}"] == 3, path
        assert counts[f"/{robot.LINKS}/left_HandPalmLink/{path}"] == 1, path
