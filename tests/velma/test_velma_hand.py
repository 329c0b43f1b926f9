"""BarrettHand control: distal = proximal / 3 on a free finger; breakaway on an obstacle
(velma/model/README.md, "BarrettHand BH8-282": the proximal link stops when it meets resistance
and the distal link keeps closing); opening re-engages the clutch.

The scene is velma.xml without gravity and with the arm and torso joints held still, plus a
fixed box in front of finger One's proximal link of the right hand (only that finger can
touch it), so each test closes real MuJoCo fingers through their servos.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from velma.control.hand import (
    BREAKAWAY_TORQUE,
    DISTAL_MAX,
    PROXIMAL_MAX,
    Hands,
)
from velma.model import VELMA_XML

SIDE = "right"
BLOCK_ANGLE = 0.7  # rad: the box touches finger One's proximal link at about this angle
DT = 0.001
DISTAL_RATIO = 1.0 / 3.0  # distal = proximal / 3 (velma/model/README.md)


def _model(obstacle: bool) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(VELMA_XML))
    spec.option.gravity = [0.0, 0.0, 0.0]
    if obstacle:
        probe = spec.compile()
        data = mujoco.MjData(probe)
        data.qpos[probe.joint(f"{SIDE}_HandFingerOneKnuckleTwoJoint").qposadr[0]] = BLOCK_ANGLE
        mujoco.mj_forward(probe, data)
        link = probe.body(f"{SIDE}_HandFingerOneKnuckleTwoLink").id
        rot = data.xmat[link].reshape(3, 3)
        # on the closing side (−y of the link frame) of the proximal capsule (radius 11 mm),
        # between its root and the distal joint (x 0.028..0.052 m of the 0.07 m link)
        centre = data.xpos[link] + rot @ np.array([0.04, -(0.011 + 0.008), 0.0])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, data.xmat[link])
        box = spec.worldbody.add_body(name="obstacle", pos=centre, quat=quat)
        box.add_geom(
            name="obstacle_geom",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[0.012, 0.008, 0.02],
            contype=1,
            conaffinity=3,
        )
    return spec.compile()


class Rig:
    """velma.xml with the non-hand joints held; ``run`` steps the hands and the physics."""

    def __init__(self, obstacle: bool) -> None:
        self.model = _model(obstacle)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        self.hands = Hands(self.model)
        self.hands.reset_from(self.data)
        held = [j for j in range(self.model.njnt) if "Hand" not in self.model.joint(j).name]
        self.held_q = self.model.jnt_qposadr[held]
        self.held_v = self.model.jnt_dofadr[held]
        self.q0 = self.data.qpos[self.held_q].copy()
        self.peak_torque = 0.0  # N·m, largest proximal servo torque of a coupled finger
        self.break_angle: np.ndarray = np.full(3, np.nan)  # measured proximal at breakaway

    def run(self, seconds: float, every: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
        """Step for ``seconds``; every ``every`` steps record (proximal, distal) measured."""
        samples = []
        prox_act = self.hands.prox_act[SIDE]
        for i in range(round(seconds / DT)):
            was_broken = self.hands.broken_away(SIDE)
            self.hands.step(self.data, DT)
            newly = self.hands.broken_away(SIDE) & ~was_broken
            self.break_angle[newly] = self.hands.proximal(self.data, SIDE)[newly]
            coupled = ~self.hands.broken_away(SIDE)
            if coupled.any():
                torque = float(np.max(self.data.actuator_force[prox_act][coupled]))
                self.peak_torque = max(self.peak_torque, torque)
            mujoco.mj_step(self.model, self.data)
            self.data.qpos[self.held_q] = self.q0
            self.data.qvel[self.held_v] = 0.0
            if every and i % every == 0:
                samples.append(
                    (
                        self.hands.proximal(self.data, SIDE).copy(),
                        self.hands.distal(self.data, SIDE).copy(),
                    )
                )
        return samples


@pytest.fixture(scope="module")
def blocked() -> Rig:
    rig = Rig(obstacle=True)
    rig.hands.command(SIDE, PROXIMAL_MAX)
    rig.run(3.0)
    return rig


def test_free_fingers_keep_the_distal_coupling() -> None:
    rig = Rig(obstacle=False)
    rig.hands.command(SIDE, PROXIMAL_MAX)
    samples = rig.run(2.5, every=50)
    for prox, dist in samples:
        assert np.allclose(dist, prox * DISTAL_RATIO, atol=0.02), (prox, dist)
    prox, dist = samples[-1]
    assert np.all(prox > PROXIMAL_MAX - 0.05)  # closed fully: nothing in the way
    assert np.allclose(dist, PROXIMAL_MAX * DISTAL_RATIO, atol=0.02)
    assert not rig.hands.broken_away(SIDE).any()
    assert rig.hands.ramp_done(SIDE)


def test_blocked_finger_stops_its_proximal_and_keeps_closing_its_distal(blocked: Rig) -> None:
    hands, data = blocked.hands, blocked.data
    prox = hands.proximal(data, SIDE)
    dist = hands.distal(data, SIDE)
    assert list(hands.broken_away(SIDE)) == [True, False, False]
    # finger One: the proximal link stopped at the box (≈ 0.7 rad) and stayed there ...
    assert 0.55 < blocked.break_angle[0] < 0.85
    assert abs(prox[0] - blocked.break_angle[0]) < 0.02
    # ... while its distal link closed to its limit, far beyond proximal / 3
    assert dist[0] > DISTAL_MAX - 0.03
    assert dist[0] > prox[0] * DISTAL_RATIO + 0.4
    # the other fingers closed freely, coupled
    assert np.all(prox[1:] > PROXIMAL_MAX - 0.05)
    assert np.allclose(dist[1:], prox[1:] * DISTAL_RATIO, atol=0.02)
    # the blocked proximal keeps pressing with about the breakaway torque (not more, not 0)
    torque = data.actuator_force[hands.prox_act[SIDE][0]]
    assert 0.5 * BREAKAWAY_TORQUE < torque < 1.2 * BREAKAWAY_TORQUE
    assert hands.ramp_done(SIDE)  # a broken-away finger has finished its ramp


def test_opening_reengages_the_clutch(blocked: Rig) -> None:
    hands, data = blocked.hands, blocked.data
    hands.command(SIDE, 0.2)
    assert not hands.broken_away(SIDE).any()
    blocked.run(2.0)
    prox = hands.proximal(data, SIDE)
    dist = hands.distal(data, SIDE)
    assert np.allclose(prox, 0.2, atol=0.03)
    assert np.allclose(dist, 0.2 * DISTAL_RATIO, atol=0.02)
    assert hands.ramp_done(SIDE)


def test_closing_without_resistance_never_breaks_away() -> None:
    """The free-closing servo torque stays well below the breakaway torque."""
    rig = Rig(obstacle=False)
    rig.hands.command(SIDE, PROXIMAL_MAX)
    rig.run(2.0)
    assert 0.0 < rig.peak_torque < 0.5 * BREAKAWAY_TORQUE
    assert not rig.hands.broken_away(SIDE).any()
