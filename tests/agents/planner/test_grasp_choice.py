"""The planner takes the grasp a_km gives for the furniture the object stands on or in
(``GraspAffordance.on``): the jar's side grasp in the cabinet, the same grip reached from above
on the table (a horizontal approach there brings the left forearm into the torso)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from services.agents.knowledge.world_model import WorldModel
from services.agents.planner.domain import _best_grasp
from services.agents.planner.knowledge import Knowledge


@pytest.mark.parametrize(
    ("where", "grasp", "approach"),
    [
        (("in", "cabinet"), "jar_side_grasp_left", (1.0, 0.0, 0.0)),
        (("on", "table"), "jar_side_grasp_left_from_above", (0.0, 0.0, -1.0)),
        (("heldBy", "left_gripper"), "jar_side_grasp_left", (1.0, 0.0, 0.0)),  # the first
    ],
)
def test_the_grasp_fits_where_the_object_is(
    where: tuple[str, str], grasp: str, approach: tuple[float, float, float]
) -> None:
    k = Knowledge()
    k.grasps[("jar", "left")] = WorldModel().grasps("jar", "left")
    chosen = _best_grasp(SimpleNamespace(k=k, where={"jar": where}), "jar", "left")
    assert chosen is not None and chosen.name == grasp and chosen.approach == approach
    both = {g.name: g.grip_in_object for g in k.grasps[("jar", "left")]}
    assert len(set(both.values())) == 1  # one grip: the jar is held the same way after either


def test_no_grasp_for_an_arm_without_one() -> None:
    k = Knowledge()
    k.grasps[("jar", "right")] = WorldModel().grasps("jar", "right")
    assert _best_grasp(SimpleNamespace(k=k, where={"jar": ("on", "table")}), "jar", "right") is None
