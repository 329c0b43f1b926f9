"""velma/perception: the head's Kinect, localisation by ICP and the content estimate, on
renders of the kitchen (320 × 240, shared by the module's fixtures)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from tests.support.machine import needs_gl
from velma.model.scene import PARTICLE_PREFIX, PARTICLE_RADIUS, initial_state, load_kitchen
from velma.perception import noise
from velma.perception.cloud import Intrinsics, incidence_angles
from velma.perception.content import estimate_content
from velma.perception.kinect import HeadKinect, aim_head
from velma.perception.localise import Localiser, ObjectEstimate
from velma.perception.objects import ObjectModel, object_model

OBJECTS = ("jar", "bowl", "cup")
SHELF_LOOK = np.array([0.7, 0.0, 0.9])  # velma/scenario.py HEAD_LOOK_CABINET
TABLE_LOOK = np.array([0.3, -0.65, 0.75])  # the table's top centre


@pytest.fixture(scope="module")
def kitchen() -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = load_kitchen()
    return model, initial_state(model)


@pytest.fixture(scope="module")
def kinect(kitchen: tuple[mujoco.MjModel, mujoco.MjData]):  # type: ignore[no-untyped-def]
    camera = HeadKinect(kitchen[0], 320, 240)
    yield camera
    camera.close()


@pytest.fixture(scope="module")
def models(kitchen: tuple[mujoco.MjModel, mujoco.MjData]) -> dict[str, ObjectModel]:
    return {n: object_model(kitchen[0], n) for n in OBJECTS}


@pytest.fixture(scope="module")
def shelf_view(kitchen, kinect, models):  # type: ignore[no-untyped-def]
    model, data = kitchen
    aim_head(model, data, SHELF_LOOK)
    frame = kinect.capture(data, np.random.default_rng(0))
    points, colours, _ = frame.cloud()
    estimates = Localiser(models.values()).localise(points, colours, frame.position)
    return frame, points, colours, estimates


def test_head_camera_is_the_kinect(kinect: HeadKinect) -> None:
    h, v = kinect.intrinsics.fov_deg
    assert v == pytest.approx(43.0)
    assert h == pytest.approx(55.4, abs=0.1)  # square pixels at 4:3 (kinect.py docstring)


@needs_gl
@pytest.mark.parametrize("name", OBJECTS)
def test_objects_on_the_shelf_are_localised_within_10_mm(kitchen, shelf_view, name: str) -> None:  # type: ignore[no-untyped-def]
    model, data = kitchen
    estimate: ObjectEstimate = shelf_view[3][name]
    assert estimate.seen, estimate.reason
    assert estimate.position is not None
    error = np.linalg.norm(estimate.position - data.xpos[model.body(name).id])
    assert error < 0.010
    assert not estimate.yaw_observable and math.isinf(estimate.yaw_sigma)  # symmetric about z
    assert estimate.quaternion is not None
    assert abs(estimate.quaternion[0]) > math.cos(math.radians(5) / 2)  # upright
    assert estimate.sigma_position < 0.005


@needs_gl
def test_objects_out_of_view_are_not_seen(kitchen, kinect, models) -> None:  # type: ignore[no-untyped-def]
    model, data = kitchen
    local = mujoco.MjData(model)
    local.qpos[:] = data.qpos
    aim_head(model, local, TABLE_LOOK)  # the shelf is behind the camera's left edge
    frame = kinect.capture(local, np.random.default_rng(1))
    points, colours, _ = frame.cloud()
    estimates = Localiser(models.values()).localise(points, colours, frame.position)
    for name in OBJECTS:
        assert not estimates[name].seen
        assert estimates[name].position is None


@needs_gl
@pytest.mark.parametrize("name", ("jar", "cup"))
def test_an_object_lifted_off_the_shelf_is_localised_at_its_height(kitchen, kinect, models, name) -> None:  # type: ignore[no-untyped-def]
    """Held 40 mm above the shelf (as a grasp lifts it), the object no longer stands on the
    plane below it: its height comes from the fit, not from the plane (segment.py ``lifted``)."""
    model, data = kitchen
    local = mujoco.MjData(model)
    local.qpos[:] = data.qpos
    local.qpos[model.jnt_qposadr[model.joint(f"{name}_free").id] + 2] += 0.04
    for b in range(model.nbody):  # the content goes up with its container
        if model.body(b).name.startswith(PARTICLE_PREFIX) and name == "jar":
            local.qpos[model.jnt_qposadr[model.body_jntadr[b] + 2]] += 0.04
    mujoco.mj_forward(model, local)
    aim_head(model, local, SHELF_LOOK)
    frame = kinect.capture(local, np.random.default_rng(2))
    points, colours, _ = frame.cloud()
    estimate = Localiser(models.values()).localise(points, colours, frame.position)[name]
    assert estimate.seen, estimate.reason
    assert estimate.position is not None
    truth = local.xpos[model.body(name).id]
    assert truth[2] - data.xpos[model.body(name).id][2] == pytest.approx(0.04)
    assert np.linalg.norm(estimate.position - truth) < 0.005


def test_noise_grows_quadratically_with_distance() -> None:
    rng = np.random.default_rng(7)
    flat = np.zeros((200, 200), dtype=np.float32)
    spread = {}
    for z in (1.0, 3.0):
        out = noise.apply_noise(flat + np.float32(z), np.zeros_like(flat), rng)
        assert np.isfinite(out).all()
        spread[z] = float(np.std(out - z))
    assert spread[1.0] == pytest.approx(1.15 * noise.random_error(1.0), rel=0.2)  # with quantisation
    assert 6.0 < spread[3.0] / spread[1.0] < 12.0  # ≈ 9 = (3/1)²


def test_noise_is_reproducible_with_a_seed() -> None:
    depth = np.full((20, 30), 1.2, dtype=np.float32)
    a = noise.apply_noise(depth, None, np.random.default_rng(3))
    b = noise.apply_noise(depth, None, np.random.default_rng(3))
    assert np.array_equal(a, b)


def test_out_of_range_is_missing() -> None:
    depth = np.array([[0.3, 1.0, 4.5]], dtype=np.float32)
    out = noise.apply_noise(depth, None, np.random.default_rng(0))
    assert np.isnan(out[0, 0]) and np.isfinite(out[0, 1]) and np.isnan(out[0, 2])


def _plane_depth(intr: Intrinsics, tilt: float) -> np.ndarray:
    """Depth of a plane through (0, 0, 1 m) whose normal is turned ``tilt`` rad from the
    optical axis about the image's x axis."""
    n = np.array([0.0, math.sin(tilt), -math.cos(tilt)])
    rays = intr.rays()
    return (n @ np.array([0.0, 0.0, 1.0]) / (rays @ n)).astype(np.float32)


def test_grazing_surfaces_return_no_depth() -> None:
    intr = Intrinsics.from_fovy(43.0, 64, 48)
    rng = np.random.default_rng(0)
    facing = _plane_depth(intr, math.radians(20))
    grazing = _plane_depth(intr, math.radians(84))
    facing_out = noise.apply_noise(facing, incidence_angles(facing, intr), rng)
    grazing_out = noise.apply_noise(grazing, incidence_angles(grazing, intr), rng)
    inner = (slice(1, -1), slice(1, -1))  # the border has no normal
    assert np.isfinite(facing_out[inner]).mean() > 0.99
    assert np.isfinite(grazing_out[inner]).mean() < 0.2


@needs_gl
def test_rendered_silhouettes_lose_depth(kitchen, kinect, shelf_view) -> None:  # type: ignore[no-untyped-def]
    _, data = kitchen
    ideal = kinect.ideal(data)
    margin = 0.01  # m: noise may carry a depth just inside the range out of it
    in_range = (ideal.depth >= noise.RANGE[0] + margin) & (ideal.depth <= noise.RANGE[1] - margin)
    lost = in_range & np.isnan(shelf_view[0].depth)
    incidence = incidence_angles(ideal.depth, ideal.intrinsics)
    grazing = ~(incidence <= noise.MAX_INCIDENCE)  # NaN (border, next to missing) counts too
    assert lost.sum() > 100  # the objects' and furniture's silhouettes, the shelf seen edge-on
    assert np.all(grazing[lost])
    assert np.all(np.isfinite(shelf_view[0].depth[in_range & ~grazing]))


@needs_gl
def test_content_of_the_start(kitchen, shelf_view, models) -> None:  # type: ignore[no-untyped-def]
    model, _ = kitchen
    frame, points, colours, estimates = shelf_view
    rgba = model.geom_rgba[model.geom(f"{PARTICLE_PREFIX}0_geom").id]
    n = sum(1 for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX))
    jar = estimate_content(
        estimates["jar"], models["jar"], points, colours, frame.position, rgba, PARTICLE_RADIUS
    )
    bowl = estimate_content(
        estimates["bowl"], models["bowl"], points, colours, frame.position, rgba, PARTICLE_RADIUS
    )
    assert jar is not None and bowl is not None
    assert abs(jar.count - n) <= 5  # the stated bound (content.py, docs/bench/perception.md)
    assert bowl.count == 0
