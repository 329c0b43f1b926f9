"""Cartesian impedance converges; a friction grasp lifts the jar (no welds)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Arm, CommandResult, Grasp, MoveTool, Observe, Release
from shared.fipa_codec.languages.l_sd import Observation
from velma.control.impedance import double_diagonalisation_damping
from velma.control.trajectory import quat_wxyz
from velma.executor.primitives import make_primitive
from velma.executor.runtime import Runtime
from velma.scenario import script_poses


def run(rt: Runtime, command: object) -> CommandResult | Observation:
    prim = make_primitive(command)  # type: ignore[arg-type]
    result = prim.start(rt)
    while result is None:
        result = prim.step(rt)
        rt.cycle()
    return result


def test_double_diagonalisation_gives_damping_ratio() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    lam = a @ a.T + 6 * np.eye(6)
    k = np.diag([1000.0, 1000, 1000, 150, 150, 150])
    d = double_diagonalisation_damping(k, lam, 0.7)
    # modal check: with Λ = Q Qᵀ, K = Q S Qᵀ, D must be Q 2ξ√S Qᵀ
    chol = np.linalg.cholesky(lam)
    li = np.linalg.inv(chol)
    s, u = np.linalg.eigh(li @ k @ li.T)
    modal = u.T @ li @ d @ li.T @ u
    assert np.allclose(modal, np.diag(2 * 0.7 * np.sqrt(s)), atol=1e-8)


def test_cartesian_impedance_converges() -> None:
    rt = Runtime(seed=0, n_particles=0)
    start = rt.grip("left").copy()
    target = pin.SE3(
        start.rotation @ pin.exp3(np.array([0.0, 0.0, 0.3])),
        start.translation + np.array([0.08, -0.05, 0.06]),
    )
    result = run(
        rt,
        MoveTool(
            arm=Arm.LEFT,
            target=Pose(position=tuple(target.translation), orientation=quat_wxyz(target.rotation)),
            duration=1.5,
        ),
    )
    assert isinstance(result, CommandResult) and result.ok, result
    for _ in range(500):
        rt.cycle()
    grip = rt.grip("left")
    assert np.linalg.norm(grip.translation - target.translation) < 2e-3
    assert np.linalg.norm(pin.log3(grip.rotation.T @ target.rotation)) < 1e-2


def test_unreachable_target_is_refused() -> None:
    rt = Runtime(seed=0, n_particles=0)
    result = run(rt, MoveTool(arm=Arm.RIGHT, target=Pose(position=(2.0, 0.0, 1.0)), duration=1.0))
    assert isinstance(result, CommandResult) and not result.ok and result.reason == "unreachable"


def test_grasp_lifts_jar_by_friction() -> None:
    rt = Runtime(seed=0, n_particles=0)
    obs = run(rt, Observe())
    assert isinstance(obs, Observation)
    poses = script_poses(obs)
    jar_id = rt.model.body("jar").id
    assert rt.model.neq == 0  # no weld or other equality constraint anywhere
    z0 = float(rt.data.xpos[jar_id][2])
    for command in (
        Release(arm=Arm.LEFT, opening=0.5),
        MoveTool(arm=Arm.LEFT, target=poses.jar_pregrasp, duration=3.0),
        MoveTool(arm=Arm.LEFT, target=poses.jar_grasp, duration=1.5),
        Grasp(arm=Arm.LEFT, spread=0.0),
    ):
        result = run(rt, command)
        assert isinstance(result, CommandResult) and result.ok, (command, result)
    hand_z0 = rt.grip("left").translation[2]
    lift = Pose(
        position=(
            poses.jar_grasp.position[0],
            poses.jar_grasp.position[1],
            poses.jar_grasp.position[2] + 0.1,
        ),
        orientation=poses.jar_grasp.orientation,
    )
    result = run(rt, MoveTool(arm=Arm.LEFT, target=lift, duration=1.5))
    assert isinstance(result, CommandResult) and result.ok, result
    for _ in range(500):
        rt.cycle()
    hand_rise = rt.grip("left").translation[2] - hand_z0
    jar_rise = float(rt.data.xpos[jar_id][2]) - z0
    assert hand_rise > 0.09
    assert jar_rise > 0.08 and math.isclose(jar_rise, hand_rise, abs_tol=0.02)
    assert rt.held["left"] == jar_id
