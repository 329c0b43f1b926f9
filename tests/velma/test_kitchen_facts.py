"""The kitchen's geometry is stated once, in the robot's scene (velma/model/kitchen_mjcf.py, built
into the MuJoCo model by velma/model/scene.py); a_km's facts about it
(services/agents/knowledge/kitchen.ttl) agree with it. The planner holds no
geometry of its own: it plans from a_km's answers, and tests/agents/planner/
test_planner_matches_script.py checks that those plans reproduce velma/scenario.py."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from services.agents.knowledge.world_model import WorldModel
from velma.model import kitchen_mjcf as kitchen
from velma.model.scene import initial_state, load_kitchen

SIZE_TOLERANCE_M = 0.011
"""How far a_km's bounding size of an object may exceed the model's geoms (a 1 cm margin
around the bowl's flared rim is stated in kitchen.ttl; none may be smaller)."""


@pytest.fixture(scope="module")
def world() -> WorldModel:
    return WorldModel()


@pytest.fixture(scope="module")
def scene() -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = load_kitchen(n_particles=0)
    return model, initial_state(model, settle_steps=0)


def _extent(model: mujoco.MjModel, data: mujoco.MjData, body: str) -> np.ndarray:
    """The axis-aligned size (x, y, z; m) of ``body``'s collision geoms in the initial state."""
    b = model.body(body).id
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for geom in range(model.ngeom):
        if model.geom_bodyid[geom] != b:
            continue
        half = model.geom_size[geom]
        kind = model.geom_type[geom]
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            r, h = half[0], half[1]
            corners = np.array(
                [[sx * r, sy * r, sz * h] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
            )
        else:
            continue
        points = corners @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]
        lo, hi = np.minimum(lo, points.min(0)), np.maximum(hi, points.max(0))
    assert np.isfinite(lo).all(), f"{body} has no box or cylinder geoms"
    return hi - lo


@pytest.mark.parametrize("obj", ["jar", "bowl", "cup"])
def test_a_kms_sizes_of_the_objects_hold_the_models_geoms(
    world: WorldModel, scene: tuple[mujoco.MjModel, mujoco.MjData], obj: str
) -> None:
    size = world.object_info(obj).size
    assert size is not None
    extent = _extent(*scene, obj)
    assert np.all(np.asarray(size) >= extent - 1e-3), (obj, size, extent)
    assert np.all(np.asarray(size) - extent <= SIZE_TOLERANCE_M), (obj, size, extent)


def test_the_jar_and_the_cup_are_the_cylinders_the_model_builds(world: WorldModel) -> None:
    for obj, radius, height in (
        ("jar", kitchen.JAR_RADIUS, kitchen.JAR_HEIGHT),
        ("cup", kitchen.CUP_RADIUS, kitchen.CUP_HEIGHT),
    ):
        assert world.object_info(obj).size == pytest.approx((2 * radius, 2 * radius, height))


def test_places_in_the_cabinet_are_where_the_model_puts_the_objects_on_its_shelf(world: WorldModel) -> None:
    for obj, where in (("jar", kitchen.JAR_POS), ("bowl", kitchen.BOWL_POS)):
        (position,) = world.placement(obj, "cabinet").positions
        assert position == pytest.approx(where)
        assert position[2] == pytest.approx(kitchen.SHELF_HEIGHT)


@pytest.mark.parametrize("obj", ["jar", "bowl", "cup"])
def test_places_on_the_table_are_on_its_top(world: WorldModel, obj: str) -> None:
    size = world.object_info(obj).size
    assert size is not None
    for x, y, z in world.placement(obj, "table").positions:
        assert z == pytest.approx(kitchen.TABLE_TOP_HEIGHT)
        for centre, at, half in (
            (kitchen.TABLE_POS[0], x, size[0] / 2),
            (kitchen.TABLE_POS[1], y, size[1] / 2),
        ):
            # to rounding: the bowl's bound (its rim's margin included) reaches the edge exactly
            assert abs(at - centre) + half <= kitchen.TABLE_HALF + 1e-9, (
                obj,
                (x, y),
                "overhangs the table",
            )


def test_the_bowls_table_place_is_the_scripts(world: WorldModel) -> None:
    """velma/scenario.py puts the bowl where a_km's ``roco:table_bowl_place`` says (the pour's
    content check depends on it: tests/velma/perception/test_content_count.py)."""
    from velma.scenario import BOWL_PLACE_POSITION

    assert world.placement("bowl", "table").positions == (BOWL_PLACE_POSITION,)


@pytest.mark.parametrize(
    ("obj", "arm", "name", "spec"),
    [
        ("jar", "left", "jar_side_grasp_left", "JAR_SIDE_GRASP"),
        ("jar", "left", "jar_side_grasp_left_from_above", "JAR_TABLE_GRASP"),
        ("bowl", "right", "bowl_rim_grasp_right", "BOWL_RIM_GRASP"),
        ("bowl", "right", "bowl_rim_grasp_right_on_table", "BOWL_TABLE_GRASP"),
    ],
)
def test_the_grasps_are_the_scripts(world: WorldModel, obj: str, arm: str, name: str, spec: str) -> None:
    """velma/scenario_kitchen.py scripts the kitchen tasks with the grasps a_km gives the
    planner (the posture, the grasp from above, the bowl's withdraw from the table: a change
    must be made in both places)."""
    import velma.scenario_kitchen as sk

    script = getattr(sk, spec)
    (known,) = [gr for gr in world.grasps(obj, arm) if gr.name == name]
    assert known.grip_in_object.position == script.grip[0]
    assert known.grip_in_object.orientation == pytest.approx(script.grip[1], abs=1e-15)
    assert (known.approach, known.distance, known.lift) == (
        script.approach,
        script.approach_distance,
        script.lift,
    )
    assert (known.retreat, known.retreat_distance) == (script.retreat, script.retreat_distance)
    assert known.posture == script.posture


@pytest.mark.parametrize(("surface", "spec"), [("table", "JAR_TABLE"), ("cabinet", "JAR_CABINET")])
def test_the_jars_places_are_the_scripts(world: WorldModel, surface: str, spec: str) -> None:
    """The jar's places in the script are a_km's: where, the torso angle, the height it comes
    down from and where the hand parks (the parks are clear of the robot itself)."""
    import velma.scenario_kitchen as sk

    script = getattr(sk, spec)
    places = world.placement("jar", surface)
    i = places.positions.index(script.position)
    facing = places.facing(i)
    assert (facing if facing is not None else world.object_info(surface).facing) == script.facing
    assert places.approach_at(i) == script.approach
    assert places.park_at(i) == script.park


PACKING = 0.5
"""The share of a container's inner volume its content's spheres fill (kitchen.ttl)."""


@pytest.mark.parametrize(
    ("obj", "radius", "height"),
    [
        (
            "jar",
            kitchen.JAR_RADIUS - kitchen.JAR_WALL,
            kitchen.JAR_HEIGHT - kitchen.JAR_BOTTOM,
        ),
        (
            "cup",
            kitchen.CUP_RADIUS - kitchen.CUP_WALL,
            kitchen.CUP_HEIGHT - kitchen.CUP_BOTTOM,
        ),
        ("bowl", kitchen.BOWL_INNER_RADIUS, kitchen.BOWL_INNER_TOP - kitchen.BOWL_BOTTOM),
    ],
)
def test_a_containers_capacity_is_what_its_inner_cylinder_takes(
    world: WorldModel, obj: str, radius: float, height: float
) -> None:
    from services.agents.knowledge.plan_check import capacity
    from velma.model.scene import N_PARTICLES, PARTICLE_RADIUS

    sphere = 4 / 3 * np.pi * PARTICLE_RADIUS**3
    takes = capacity(world, obj)
    assert takes == int(PACKING * np.pi * radius**2 * height / sphere)
    assert takes is not None and takes >= N_PARTICLES  # each takes the jar's content


def test_the_place_areas_are_the_table_top_and_the_cabinet_shelf(world: WorldModel) -> None:
    from services.agents.knowledge.plan_check import place_area

    tx, ty, _ = kitchen.TABLE_POS
    assert place_area(world, "table") == pytest.approx(
        (
            tx - kitchen.TABLE_HALF,
            ty - kitchen.TABLE_HALF,
            tx + kitchen.TABLE_HALF,
            ty + kitchen.TABLE_HALF,
        )
    )
    cx, cy, _ = kitchen.CABINET_POS
    depth, width = kitchen.CABINET_HALF
    inside = width - 2 * kitchen.PANEL
    assert place_area(world, "cabinet") == pytest.approx(
        (cx - depth, cy - inside, cx + depth - 2 * kitchen.PANEL, cy + inside)
    )


@pytest.mark.parametrize(
    ("obj", "surface"),
    [("jar", "table"), ("bowl", "table"), ("cup", "table"), ("jar", "cabinet"), ("bowl", "cabinet")],
)
def test_every_place_lies_inside_its_area(world: WorldModel, obj: str, surface: str) -> None:
    """The put-down check (plan_check.py) accepts every place kitchen.ttl states."""
    from services.agents.knowledge.plan_check import footprint, place_area

    area = place_area(world, surface)
    assert area is not None
    r = footprint(world.object_info(obj)) / 2
    for x, y, _z in world.placement(obj, surface).positions:
        assert area[0] + r <= x <= area[2] - r and area[1] + r <= y <= area[3] - r, (obj, surface, (x, y))


MASS_TOLERANCE_KG = 0.01
"""How far a_km's mass of an object (its payload prior) may be from the model's: within the
wrist F/T identification's settling (velma/control/payload_estimate.py)."""


@pytest.mark.parametrize("obj", ["jar", "bowl", "cup"])
def test_a_kms_masses_of_the_objects_are_the_models_with_their_content(world: WorldModel, obj: str) -> None:
    model = load_kitchen()  # with the content spheres
    content = [b for b in range(model.nbody) if model.body(b).name.startswith(f"{obj}_content_")]
    truth = float(model.body_mass[model.body(obj).id] + sum(model.body_mass[b] for b in content))
    mass = world.object_info(obj).mass
    assert mass is not None and abs(mass - truth) <= MASS_TOLERANCE_KG, (obj, mass, truth)
