"""velma/perception/content.py ``count_spheres`` and the tipped fit of localise.py on 640 × 480
renders: the bowl on the table where the pour leaves it, seen from the head as at the pour's
content check, its spheres laid out as the frictionless pour leaves them (a ring along the
wall, a few inside)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from services.agents.planner.domain import CONTENT_SHARE_REQUIRED
from services.agents.task_executor.verdict import Answer, Do, Step, Verdict, judge
from shared.fipa_codec.languages.l_hfsm import CheckContent, PlanNode
from shared.fipa_codec.languages.l_sd import ObjectObservation
from tests.support.machine import needs_gl
from velma.executor.capture import WorldCapture
from velma.executor.observer import CameraObserver
from velma.model.scene import N_PARTICLES, PARTICLE_PREFIX, PARTICLE_RADIUS, initial_state, load_kitchen
from velma.perception.content import SphereCount, _ring_radius, count_spheres
from velma.perception.kinect import HeadKinect, aim_head
from velma.perception.localise import Localiser
from velma.perception.objects import object_model
from velma.scenario import BOWL_PLACE_POSITION, TORSO_POUR

pytestmark = needs_gl

R = PARTICLE_RADIUS


@pytest.fixture(scope="module")
def scene():  # type: ignore[no-untyped-def]
    model = load_kitchen()
    kinect = HeadKinect(model)
    bowl = object_model(model, "bowl")
    localiser = Localiser([bowl])
    yield model, kinect, bowl, localiser
    kinect.close()


def _layout(bowl_model, vacancies: tuple[int, ...]) -> np.ndarray:  # type: ignore[no-untyped-def]
    """18 sphere centres (bowl frame): 14 ring places along the wall less ``vacancies``, the
    rest inside (the pour's layout, docs/bench/observe.md), as many as make 18."""
    ring = _ring_radius(bowl_model, 0.006 + R, R) - 0.0005
    places = [k for k in range(14) if k not in vacancies]
    out = [(ring * math.cos(2 * math.pi * k / 14), ring * math.sin(2 * math.pi * k / 14)) for k in places]
    angles = np.arange(4) * math.pi / 2 + 0.4
    inner = [(0.0, 0.0), *((0.024 * math.cos(a), 0.024 * math.sin(a)) for a in angles)]
    out += inner[: 18 - len(out)]
    return np.array([(x, y, 0.006 + R) for x, y in out])


def _state(model: mujoco.MjModel, centres: np.ndarray, spilled: np.ndarray | None = None) -> mujoco.MjData:
    """The bowl standing at BOWL_PLACE_POSITION with spheres at ``centres`` (bowl frame), the
    next ones at ``spilled`` (world), the others far below the floor; the torso at TORSO_POUR,
    the head on the bowl."""
    spilled = np.zeros((0, 3)) if spilled is None else spilled
    data = initial_state(model)
    qa = model.jnt_qposadr[model.joint("bowl_free").id]
    data.qpos[qa : qa + 3] = BOWL_PLACE_POSITION
    data.qpos[qa + 3 : qa + 7] = (1.0, 0.0, 0.0, 0.0)
    data.qpos[model.jnt_qposadr[model.joint("torso_0_joint").id]] = TORSO_POUR
    mujoco.mj_forward(model, data)
    names = [model.body(b).name for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX)]
    for i, name in enumerate(names):
        b = model.body(name).id
        rest = data.xpos[b] - [data.qpos[model.jnt_qposadr[model.body_jntadr[b] + k]] for k in range(3)]
        gone = rest + np.array([0.0, 0.0, -5.0])  # far below the floor: not in the scene
        goal = np.array(BOWL_PLACE_POSITION) + centres[i] if i < len(centres) else gone
        if len(centres) <= i < len(centres) + len(spilled):
            goal = spilled[i - len(centres)]
        for k in range(3):
            data.qpos[model.jnt_qposadr[model.body_jntadr[b] + k]] = goal[k] - rest[k]
    aim_head(model, data, np.array(BOWL_PLACE_POSITION) + np.array([0.0, 0.0, 0.03]))
    return data


def _observe(scene, centres: np.ndarray, seed: int = 0) -> tuple[SphereCount, int]:  # type: ignore[no-untyped-def]
    """Count the spheres of ``centres`` (bowl frame; the others far below the floor) in the
    bowl standing at BOWL_PLACE_POSITION, the torso at TORSO_POUR, the head on the bowl."""
    model, kinect, bowl_model, localiser = scene
    data = _state(model, centres)
    frame = kinect.capture(data, np.random.default_rng(seed), 5)
    points, colours, _ = frame.cloud()
    estimate = localiser.localise(points, colours, frame.position)["bowl"]
    rgba = model.geom_rgba[model.geom(f"{PARTICLE_PREFIX}0_geom").id]
    k = frame.intrinsics
    count = count_spheres(
        estimate, bowl_model, points, colours, frame.depth, frame.position, frame.rotation,
        k.fx, k.cx, k.cy, rgba, R,
    )  # fmt: skip
    assert count is not None
    return count, len(centres)


VACANCY = (10,)
"""The ring place left empty: on the side the camera sees (a vacancy in the hidden arc is
counted full, content.py's named simplification)."""


def test_the_ring_hidden_behind_the_near_wall_is_inferred(scene) -> None:  # type: ignore[no-untyped-def]
    count, truth = _observe(scene, _layout(scene[2], VACANCY))
    assert count.ring_visible < 0.8  # the near wall hides part of the ring
    assert count.visible < truth - 1 and count.hidden >= 2
    assert abs(count.count - truth) <= 1


def test_spheres_missing_where_the_camera_sees_lower_the_count(scene) -> None:  # type: ignore[no-untyped-def]
    centres = _layout(scene[2], VACANCY)
    full, _ = _observe(scene, centres)
    # three ring spheres on the far side (ring places 0, 1 and 13 are in view)
    count, truth = _observe(scene, np.delete(centres, [0, 1, 12], axis=0))
    assert truth == 15
    assert count.count <= truth + 1 < full.count


def test_an_upside_down_bowl_is_seen_with_its_tilt(scene) -> None:  # type: ignore[no-untyped-def]
    model, kinect, _, localiser = scene
    data = initial_state(model)
    qa = model.jnt_qposadr[model.joint("bowl_free").id]
    data.qpos[qa : qa + 3] = BOWL_PLACE_POSITION
    data.qpos[qa + 2] += 0.061  # on its rim
    data.qpos[qa + 3 : qa + 7] = (0.0, 1.0, 0.0, 0.0)  # turned π about x
    data.qpos[model.jnt_qposadr[model.joint("torso_0_joint").id]] = TORSO_POUR
    mujoco.mj_forward(model, data)
    aim_head(model, data, np.array(BOWL_PLACE_POSITION) + np.array([0.0, 0.0, 0.03]))
    frame = kinect.capture(data, np.random.default_rng(1), 5)
    points, colours, _ = frame.cloud()
    e = localiser.localise(points, colours, frame.position)["bowl"]
    assert e.seen and e.position is not None and e.quaternion is not None, e.reason
    w, _, _, z = e.quaternion
    tilt = 2 * math.acos(min(1.0, math.hypot(w, z)))
    assert tilt > math.radians(170)
    assert np.linalg.norm(e.position - data.xpos[model.body("bowl").id]) < 0.01


def test_the_upright_cup_is_not_taken_for_an_upside_down_bowl(scene) -> None:  # type: ignore[no-untyped-def]
    model, kinect, _, localiser = scene
    data = initial_state(model)
    qa = model.jnt_qposadr[model.joint("bowl_free").id]
    data.qpos[qa : qa + 3] = (3.0, 3.0, 0.0)  # the bowl far out of view: the cup stays on the shelf
    mujoco.mj_forward(model, data)
    aim_head(model, data, np.array([0.7, 0.0, 0.9]))  # the shelf (velma/scenario.py HEAD_LOOK_CABINET)
    frame = kinect.capture(data, np.random.default_rng(2), 5)
    points, colours, _ = frame.cloud()
    e = localiser.localise(points, colours, frame.position)["bowl"]
    assert not e.seen, e.position


NEAR_WALL = [5, 6, 7]
"""Ring places (of ``_layout`` with ``VACANCY``) behind the bowl's near wall, out of view."""
TABLE_BESIDE = np.array([[-0.12 + 0.03 * j, 0.10, R] for j in range(3)])
"""Table places beside the bowl (from BOWL_PLACE_POSITION), in the head camera's view."""


def test_spheres_spilled_in_view_cap_the_bowls_count(scene) -> None:  # type: ignore[no-untyped-def]
    """Three spheres of the ring behind the near wall lie on the table instead: the wall's
    inference alone counts the bowl nearly full; the spheres seen outside (spill.py) make the
    Observation's count at most what the conservation of the content leaves."""
    model = scene[0]
    centres = _layout(scene[2], VACANCY)
    out = np.array(BOWL_PLACE_POSITION) + TABLE_BESIDE
    data = _state(model, np.delete(centres, NEAR_WALL, axis=0), out)
    observer = CameraObserver(model, seed=0)
    try:
        obs, seen = observer.observe(WorldCapture.of(("bowl",), 0.0, data.qpos))
    finally:
        observer.close()
    bowl = next(o for o in obs.objects if o.name == "bowl")
    inferred = seen.content["bowl"]
    assert obs.particles_outside == 3
    assert seen.outside is not None and np.allclose(seen.outside.centres[:, 2], out[0, 2], atol=0.003)
    assert inferred.count >= 17  # the wall hides the gap: inferred as full as the ring's neighbours make it
    assert bowl.particles_inside is not None and bowl.particles_inside <= obs.total_particles - 3
    assert bowl.particles_inside / obs.total_particles < CONTENT_SHARE_REQUIRED  # a_ta's check fails


def test_no_content_outside_when_all_is_in_the_bowl(scene) -> None:  # type: ignore[no-untyped-def]
    model = scene[0]
    data = _state(model, _layout(scene[2], VACANCY))
    observer = CameraObserver(model, seed=1)
    try:
        obs, _ = observer.observe(WorldCapture.of(("bowl",), 0.0, data.qpos))
    finally:
        observer.close()
    assert obs.particles_outside == 0
    bowl = next(o for o in obs.objects if o.name == "bowl")
    assert bowl.particles_inside is not None and bowl.particles_inside >= 17


def _bowl_checked(model: mujoco.MjModel, data: mujoco.MjData, look: int) -> tuple[ObjectObservation, Verdict]:
    """The camera's Observation of the bowl in ``data`` and a_ta's verdict on it as the pour's
    content check (services/agents/task_executor/verdict.py) at look ``look`` (1 or 2)."""
    observer = CameraObserver(model, seed=0)
    try:
        obs, _ = observer.observe(WorldCapture.of(("bowl",), 0.0, data.qpos))
    finally:
        observer.close()
    check = CheckContent(container="bowl", min_fraction=CONTENT_SHARE_REQUIRED)
    step = Step(
        "pour/check_bowl", PlanNode(name="check_bowl", action=check), second_view=0 if look == 1 else 2
    )
    verdict = judge(step, Answer(True, obs, "inform", "inform"), False)
    return next(o for o in obs.objects if o.name == "bowl"), verdict


def test_the_check_looks_again_when_inferred_spheres_decide_and_says_what_it_rests_on(scene) -> None:  # type: ignore[no-untyped-def]
    """The bowl full (18 of 18): the camera sees 15 (83 %) and infers 3 behind the near wall,
    so a_ta looks a second time; from the same head the second look sees no more, and the
    task succeeds saying it rests on the 3 inferred. Two spheres taken from the hidden arc
    (16 of 18, under 90 %) change nothing the camera sees, so neither the count nor the
    verdict changes: content.py's named simplification, which the verdict's words name and
    scripts/bench_pour_seeds.py's comparison with the simulation's truth catches."""
    model = scene[0]
    centres = _layout(scene[2], VACANCY)
    full = _state(model, centres)
    bowl, first = _bowl_checked(model, full, 1)
    assert (bowl.particles_inside, bowl.particles_inferred) == (18, 3)
    assert first.do is Do.LOOK
    assert first.reason == "only 15 of 18 spheres seen in the bowl, 3 more inferred behind its wall"
    _, second = _bowl_checked(model, full, 2)
    assert second.do is Do.NEXT and second.reason is not None
    assert second.reason.endswith("the 90 % rests on the 3 inferred, which no look saw")
    taken = np.delete(centres, NEAR_WALL[:2], axis=0)
    assert len(taken) / N_PARTICLES < CONTENT_SHARE_REQUIRED
    bowl_taken, verdict_taken = _bowl_checked(model, _state(model, taken), 2)
    assert (bowl_taken.particles_inside, bowl_taken.particles_inferred) == (18, 3)
    assert verdict_taken.do is second.do and verdict_taken.reason == second.reason
