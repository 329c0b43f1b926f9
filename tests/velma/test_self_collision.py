"""Self-collision: Velma's links collide with each other in MuJoCo, the excluded
pairs follow stated rules, the IK rejects postures in self-collision and the wrist band pushes
a hand away from its own forearm."""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Generator

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from velma.control.hand import ContactMonitor
from velma.control.ik import solve_ik_multi
from velma.control.joints import SIDES, arm_joints
from velma.control.robot_model import RobotModel
from velma.control.self_collision import (
    CHECK_STEPS,
    WRIST_BAND,
    SelfCollision,
    wrist_band_torque,
    wrist_field,
)
from velma.model import VELMA_XML
from velma.model.robot_mjcf import SELF_COLLISION_EXCLUDES

# the left wrist of the pour's first reach before the IK knew about self-collision: the
# palm's F/T housing 1 mm into the forearm
TOUCHING = {5: -0.42, 6: 0.47}


def _model(excludes: bool = True) -> mujoco.MjModel:
    text = VELMA_XML.read_text()
    if not excludes:
        text = re.sub(r"<contact>.*?</contact>", "", text, flags=re.S)
    return mujoco.MjModel.from_xml_string(text)


def _touching_pairs(model: mujoco.MjModel, data: mujoco.MjData) -> set[frozenset[str]]:
    mujoco.mj_forward(model, data)
    return {
        frozenset((model.body(model.geom_bodyid[c.geom1]).name, model.body(model.geom_bodyid[c.geom2]).name))
        for c in data.contact[: data.ncon]
        if c.dist < 0.0
    }


def test_the_excluded_pairs_are_those_the_rules_give() -> None:
    """Without the excludes: the pairs touching in the zero configuration or in ≥ 95 % of
    1000 random configurations, and the bodies joined through a body without geometry, are
    exactly SELF_COLLISION_EXCLUDES."""
    model = _model(excludes=False)
    data = mujoco.MjData(model)
    default = _touching_pairs(model, data)
    rng = np.random.default_rng(0)
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    counts: Counter[frozenset[str]] = Counter()
    samples = 1000
    for _ in range(samples):
        data.qpos[:] = lo + (hi - lo) * rng.random(model.nq)
        counts.update(_touching_pairs(model, data))
    always = {pair for pair, n in counts.items() if n >= 0.95 * samples}
    bare = {b for b in range(1, model.nbody) if not any(model.geom_bodyid == b)}
    through_bare = {
        frozenset((model.body(model.body_parentid[b]).name, model.body(c).name))
        for b in bare
        for c in range(model.nbody)
        if model.body_parentid[c] == b
    }
    assert default | always | through_bare == {frozenset(p) for p in SELF_COLLISION_EXCLUDES}


def test_the_robot_touching_itself_is_seen() -> None:
    """Self-collision is on: the left wrist bent into its hand makes robot–robot contacts,
    which ``ContactMonitor.self_contacts`` reports; the straight wrist makes none."""
    model = _model()
    data = mujoco.MjData(model)
    monitor = ContactMonitor(model)
    mujoco.mj_forward(model, data)
    assert monitor.self_contacts(data) == []
    for k, value in TOUCHING.items():
        data.qpos[model.joint(f"left_arm_{k}_joint").qposadr[0]] = value - 0.1  # 1 mm is too little
    mujoco.mj_forward(model, data)
    names = {
        frozenset((model.geom(a).name or model.body(model.geom_bodyid[a]).name, model.geom(b).name or ""))
        for a, b in monitor.self_contacts(data)
    }
    assert any("left_ft_geom" in pair for pair in names), names


def test_the_wrist_table_is_the_exact_distance_within_its_resolution() -> None:
    """The bilinear table against coal's exact distances at 200 random wrist postures: within
    2 mm (0.05 rad steps), and the straight wrist ≈ 20 mm clear."""
    robot = RobotModel()
    field = wrist_field()
    checker = SelfCollision(robot, margin=0.0)
    geometry = checker.geometry["left"]
    gdata = pin.GeometryData(geometry)
    objects = geometry.geometryObjects
    frames = [robot.model.frames[g.parentFrame].name for g in objects]
    pairs = [
        k
        for k, p in enumerate(geometry.collisionPairs)
        if {frames[p.first], frames[p.second]} == {"left_arm_5_link", "left_HandPalmLink"}
    ]
    assert pairs
    data = robot.model.createData()
    q = pin.neutral(robot.model)
    i5, i6 = (robot.v_index(j) for j in arm_joints("left")[5:])
    rng = np.random.default_rng(3)
    for _ in range(200):
        q[i5], q[i6] = rng.uniform(-2.0, 2.0), rng.uniform(-2.9, 2.9)
        pin.forwardKinematics(robot.model, data, q)
        pin.updateGeometryPlacements(robot.model, data, geometry, gdata)
        exact = min(pin.computeDistance(geometry, gdata, k).min_distance for k in pairs)
        table, _, _ = field.sample(SIDES.index("left"), float(q[i5]), float(q[i6]))
        if exact > -0.01:  # deep overlaps: only the sign matters there
            assert abs(table - exact) < 2e-3, (q[i5], q[i6], table, exact)
    straight, _, _ = field.sample(SIDES.index("left"), 0.0, 0.0)
    assert 0.018 < straight < 0.022


def test_the_wrist_band_pushes_the_hand_away_from_its_forearm() -> None:
    """Inside the band the torque on joints 5 and 6 increases the distance; outside it is
    zero; approaching is damped."""
    field = wrist_field()
    k = SIDES.index("left")
    q = np.zeros(7)
    q[5], q[6] = TOUCHING[5], TOUCHING[6]
    still = wrist_band_torque(field, k, q, np.zeros(7))
    assert still is not None
    d0, _, _ = field.sample(k, q[5], q[6])
    step = 0.01 * np.array(still) / np.hypot(*still)
    d1, _, _ = field.sample(k, q[5] + step[0], q[6] + step[1])
    assert d1 > d0
    v = np.zeros(7)
    v[5], v[6] = -step[0] * 100.0, -step[1] * 100.0  # moving into the forearm
    approaching = wrist_band_torque(field, k, q, v)
    assert approaching is not None and np.hypot(*approaching) > np.hypot(*still)
    assert wrist_band_torque(field, k, np.zeros(7), np.zeros(7)) is None  # straight: outside


def test_the_ik_finds_a_posture_clear_of_the_robot_itself() -> None:
    """A grip pose reached first by a posture with the hand on its own forearm (the pour's
    first reach): with the check, the IK returns another posture for the same pose, outside
    the wrist band and touching nothing; without it, the touching one."""
    robot = RobotModel()
    q0 = pin.neutral(robot.model)
    idx = robot.v_indices(arm_joints("left"))
    q0[idx] = (-0.09, 1.7, -0.27, -1.31, 0.22, TOUCHING[5], TOUCHING[6])
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q0)
    target = data.oMf[robot.grip_frame_id["left"]].copy()
    check = SelfCollision(robot)
    unchecked = solve_ik_multi(robot, "left", target, q0)
    assert unchecked.ok and np.allclose(unchecked.q[idx], q0[idx], atol=1e-6)
    checked = solve_ik_multi(robot, "left", target, q0, self_collision=check)
    assert checked.ok and checked.self_collision is None
    d, _, _ = wrist_field().sample(SIDES.index("left"), float(checked.q[idx][5]), float(checked.q[idx][6]))
    assert d >= WRIST_BAND
    pin.framesForwardKinematics(robot.model, data, checked.q)
    assert check.colliding(data, "left", checked.q[idx]) is None
    assert np.linalg.norm(data.oMf[robot.grip_frame_id["left"]].translation - target.translation) < 2e-3


@pytest.mark.parametrize("side", SIDES)
def test_the_check_names_the_touching_pair(side: str) -> None:
    robot = RobotModel()
    check = SelfCollision(robot)
    q = pin.neutral(robot.model)
    idx = robot.v_indices(arm_joints(side))
    sign = -1.0 if side == "left" else 1.0  # the brackets are mirrored
    q[idx[5]], q[idx[6]] = sign * 0.6, TOUCHING[6]
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    assert check.colliding(data, side) == (f"{side}_arm_5_linkGeom_0", f"{side}_ft_geom")
    assert check.colliding(data, side, q[idx]) == (f"{side}_HandPalmLink", f"{side}_arm_5_link")
    other = SIDES[1 - SIDES.index(side)]
    assert check.colliding(data, other) is None  # a contact of one arm does not block the other


def _drain(steps: Generator[None, None, tuple[str, str] | None]) -> tuple[int, tuple[str, str] | None]:
    """How many times a generator yields, and what it returns."""
    yields = 0
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            return yields, stop.value
        yields += 1


@pytest.mark.parametrize("side", SIDES)
def test_the_check_in_slices_finds_what_the_whole_check_finds(side: str) -> None:
    """``colliding_steps`` (the IK's resumable form) answers as ``colliding``: the
    same pair at a touching posture, None at a free one after ``CHECK_STEPS`` slices; its
    slices together hold every pair of the side once."""
    robot = RobotModel()
    check = SelfCollision(robot)
    idx = robot.v_indices(arm_joints(side))
    data = robot.model.createData()
    q = pin.neutral(robot.model)
    pin.forwardKinematics(robot.model, data, q)
    assert check.colliding(data, side) is None
    assert _drain(check.colliding_steps(data, side)) == (CHECK_STEPS - 1, None)
    sign = -1.0 if side == "left" else 1.0
    q[idx[5]], q[idx[6]] = sign * 0.6, TOUCHING[6]
    pin.forwardKinematics(robot.model, data, q)
    assert _drain(check.colliding_steps(data, side))[1] == check.colliding(data, side) is not None
    assert _drain(check.colliding_steps(data, side, q[idx])) == (0, check.colliding(data, side, q[idx]))

    def pairs(geometry: pin.GeometryModel) -> list[tuple[int, int]]:
        return [(p.first, p.second) for p in geometry.collisionPairs]

    parts = [pairs(part) for part, _ in check.slices[side]]
    assert len(parts) == CHECK_STEPS and all(parts)
    assert [p for part in parts for p in part] == pairs(check.geometry[side])


def test_a_command_during_which_the_robot_touches_itself_names_the_pair() -> None:
    """The loop reports robot–robot contact per command (``CommandResult.self_contacts``):
    none for a Wait in the home posture; the touching pair for a Wait with the left wrist
    bent into its forearm (the scene's record of it, services/report/timeline.py)."""
    from shared.fipa_codec.languages.l_ex import CommandResult, Wait
    from velma.executor.loop import ControlLoop
    from velma.executor.runtime import Runtime

    rt = Runtime(seed=0)
    loop: ControlLoop[int] = ControlLoop(rt)

    def wait() -> CommandResult:
        loop.submit(0, Wait(duration=0.03))
        while (done := loop.cycle()) is None:
            pass
        assert isinstance(done[1], CommandResult) and done[1].ok
        return done[1]

    assert wait().self_contacts == ()
    for k, value in TOUCHING.items():
        rt.data.qpos[rt.model.joint(f"left_arm_{k}_joint").qposadr[0]] = value - 0.1
    mujoco.mj_forward(rt.model, rt.data)
    rt.ctrl.hold("left", rt.q()[rt.ctrl.arm_slice["left"]].copy())
    touched = wait().self_contacts
    assert any("left_ft_geom" in pair for pair in touched), touched
    assert all(" + " in pair for pair in touched)
