"""Kitchen scene: jar and bowl pose randomisation (pose_seed) and the jar's content."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from velma.model.scene import (
    PARTICLE_PREFIX,
    PARTICLE_RADIUS,
    POSE_OFFSET_MAX,
    POSE_YAW_MAX,
    build_spec,
    initial_state,
    load_kitchen,
    particle_names,
    scene_perturbation,
)

NOMINAL = {"jar": (0.70, 0.2, 0.85), "bowl": (0.70, -0.2, 0.85)}  # kitchen.xml
SEEDS = (0, 1, 2, 7, 123)


def _yaw(quat: np.ndarray) -> float:
    """Angle of a rotation about z (asserts that it is one)."""
    w, x, y, z = quat
    assert abs(x) < 1e-12 and abs(y) < 1e-12
    return 2.0 * math.atan2(z, w)


def _content_in_jar(model: mujoco.MjModel, data: mujoco.MjData, margin: float) -> np.ndarray:
    """(n,) bool: each content sphere lies inside the jar's inner cylinder, shrunk by
    ``margin`` m (radially and at both ends)."""
    site = model.site("jar_inner").id
    radius, half = model.site_size[site][:2]
    rot = data.site_xmat[site].reshape(3, 3)
    ids = [b for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX)]
    assert ids, "no content spheres in the model"
    local = (data.xpos[ids] - data.site_xpos[site]) @ rot
    radial = np.hypot(local[:, 0], local[:, 1])
    inside: np.ndarray = (radial <= radius - margin) & (np.abs(local[:, 2]) <= half - margin)
    return inside


def test_no_pose_seed_keeps_todays_scene_exactly() -> None:
    model = load_kitchen(27, 0)
    assert build_spec(27, 0, pose_seed=None).compile().nbody == model.nbody
    for name, pos in NOMINAL.items():
        assert list(model.body(name).pos) == list(pos)
        assert list(model.body(name).quat) == [1.0, 0.0, 0.0, 0.0]
    # start positions of the content as computed before pose_seed existed (commit 8a83e31)
    start = np.array([model.body(n).pos for n in particle_names(27)])
    assert start[0].tolist() == [0.7224108850619643, 0.1993093601412916, 0.867]
    assert start[-1].tolist() == [0.6962339921453932, 0.17722729003641546, 0.945]
    assert np.allclose(start.sum(axis=0), [18.89229922094422, 5.415094203861584, 24.462], rtol=0, atol=1e-12)
    p = scene_perturbation(None)
    assert p.seed is None and p.as_dict() == {
        "jar": {"dx": 0.0, "dy": 0.0, "yaw": 0.0},
        "bowl": {"dx": 0.0, "dy": 0.0, "yaw": 0.0},
    }


@pytest.mark.parametrize("seed", SEEDS)
def test_perturbed_poses_stay_within_bounds_and_match_the_report(seed: int) -> None:
    model = load_kitchen(27, 0, pose_seed=seed)
    applied = scene_perturbation(seed).objects()
    for name, nominal in NOMINAL.items():
        pos = np.array(model.body(name).pos)
        offset = pos - np.array(nominal)
        assert np.all(np.abs(offset[:2]) <= POSE_OFFSET_MAX) and offset[2] == 0.0
        yaw = _yaw(np.array(model.body(name).quat))
        assert abs(yaw) <= POSE_YAW_MAX
        assert POSE_OFFSET_MAX == 0.02 and math.isclose(POSE_YAW_MAX, math.radians(10.0))
        assert np.allclose(offset[:2], [applied[name].dx, applied[name].dy], atol=1e-15)
        assert math.isclose(yaw, applied[name].yaw, abs_tol=1e-12)
    # a real perturbation: the jar moved (the chance of a < 1 mm draw is negligible here)
    assert np.linalg.norm(np.array(model.body("jar").pos) - np.array(NOMINAL["jar"])) > 1e-3


def test_pose_seed_is_deterministic_and_seeds_differ() -> None:
    a = load_kitchen(27, 0, pose_seed=5)
    b = load_kitchen(27, 0, pose_seed=5)
    c = load_kitchen(27, 0, pose_seed=6)
    for name in ("jar", "bowl"):
        assert np.array_equal(a.body(name).pos, b.body(name).pos)
        assert np.array_equal(a.body(name).quat, b.body(name).quat)
        assert not np.array_equal(a.body(name).pos, c.body(name).pos)
    assert np.array_equal(a.qpos0, b.qpos0)
    assert scene_perturbation(5) == scene_perturbation(5) != scene_perturbation(6)
    # the content jitter (seed) and the pose randomisation (pose_seed) are independent
    d = load_kitchen(27, 1, pose_seed=5)
    assert np.array_equal(a.body("jar").pos, d.body("jar").pos)
    assert not np.array_equal(a.body("jar_content_0").pos, d.body("jar_content_0").pos)


def test_perturbation_spans_the_bounds() -> None:
    """Over many seeds the draws cover most of ±2 cm and ±10° (not a constant offset)."""
    draws = [scene_perturbation(s) for s in range(200)]
    dx = np.array([p.jar.dx for p in draws] + [p.bowl.dx for p in draws])
    yaw = np.array([p.jar.yaw for p in draws] + [p.bowl.yaw for p in draws])
    assert dx.max() > 0.9 * POSE_OFFSET_MAX and dx.min() < -0.9 * POSE_OFFSET_MAX
    assert yaw.max() > 0.9 * POSE_YAW_MAX and yaw.min() < -0.9 * POSE_YAW_MAX


@pytest.mark.parametrize("seed", (None, 1, 7))
def test_content_starts_and_settles_inside_the_moved_jar(seed: int | None) -> None:
    model = load_kitchen(27, 0, pose_seed=seed)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert _content_in_jar(model, data, PARTICLE_RADIUS).all()
    jar_before = data.xpos[model.body("jar").id].copy()
    bowl_before = data.xpos[model.body("bowl").id].copy()
    data = initial_state(model)
    assert _content_in_jar(model, data, 0.0).all()
    # the containers stand where they were put (nothing in the way of a moved object)
    assert np.linalg.norm(data.xpos[model.body("jar").id] - jar_before) < 2e-3
    assert np.linalg.norm(data.xpos[model.body("bowl").id] - bowl_before) < 2e-3


def test_content_is_frictionless_and_moves_on_three_slide_joints() -> None:
    """Every contact of a content sphere is frictionless (condim 1), whatever it touches, so the
    sphere's rotation is decoupled and it has only x, y, z slide joints (velma/model/scene.py)."""
    model = load_kitchen(18, 0)
    data = initial_state(model)
    content = {model.body(n).id for n in particle_names(18)}
    for b in content:
        first, count = model.body_jntadr[b], model.body_jntnum[b]
        assert count == 3
        assert all(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE for j in range(first, first + count))
        axes = np.array([model.jnt_axis[j] for j in range(first, first + count)])
        assert np.allclose(axes, np.eye(3))
    touching = [c for c in data.contact[: data.ncon] if {int(model.geom_bodyid[g]) for g in c.geom} & content]
    walls = [c for c in touching if not {int(model.geom_bodyid[g]) for g in c.geom} <= content]
    assert walls, "the settled content touches the jar"
    assert all(c.dim == 1 for c in touching)


def test_displacing_the_jar_carries_its_content() -> None:
    from velma.executor.runtime import Runtime

    rt = Runtime(seed=0)
    ids = [rt.model.body(n).id for n in particle_names()]
    before_jar = rt.data.body("jar").xpos.copy()
    before = rt.data.xpos[ids].copy()
    rt.displace("jar", (0.03, -0.02, 0.0))
    assert np.allclose(rt.data.body("jar").xpos - before_jar, [0.03, -0.02, 0.0], atol=1e-9)
    assert np.allclose(rt.data.xpos[ids] - before, [0.03, -0.02, 0.0], atol=1e-9)
    dofs = [
        rt.model.jnt_dofadr[j]
        for b in ids
        for j in range(rt.model.body_jntadr[b], rt.model.body_jntadr[b] + 3)
    ]
    assert not np.any(rt.data.qvel[dofs])


def test_knocking_the_jar_over_turns_it_and_its_content_about_world_x() -> None:
    from velma.executor.runtime import Runtime

    rt = Runtime(seed=0)
    ids = [rt.model.body(n).id for n in particle_names()]
    origin = rt.data.body("jar").xpos.copy()
    before = rt.data.xpos[ids].copy()
    rt.displace("jar", (0.0, 0.0, 0.05), tilt=math.pi / 2)
    z_axis = rt.data.body("jar").xmat.reshape(3, 3)[:, 2]
    assert np.allclose(z_axis, [0.0, -1.0, 0.0], atol=1e-3)  # lying on its side, mouth to −y
    turn = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    expected = origin + (before - origin) @ turn.T + [0.0, 0.0, 0.05]
    assert np.allclose(rt.data.xpos[ids], expected, atol=1e-9)
