"""The compiled impedance law (velma/control/compiled.py) against its Python reference
(velma/control/impedance.py): the same torques, errors, grip poses and rate-limit state for
random states in every mode and branch, and the same motion of the simulated robot."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from tests.support.arms import lift_both_arms
from velma.control import compiled
from velma.control.compiled import ENV_LAW, CompiledController, compiled_available, make_controller
from velma.control.impedance import DEFAULT_CART_STIFFNESS, SafetyLimits, VelmaController
from velma.control.joints import SIDES
from velma.control.payload import NO_PAYLOAD, Payload
from velma.control.robot_model import RobotModel
from velma.executor.runtime import Runtime

pytestmark = pytest.mark.skipif(not compiled_available(), reason="the compiled law is not built")

MODES = ("cart", "joint", "safe")


def _command(ctrl: VelmaController, trial: int) -> None:
    """The same random commands on ``ctrl`` for the same ``trial``: every mode pairing,
    zero and positive stiffnesses, scalar and per-joint joint stiffness, a payload or none."""
    for k, side in enumerate(SIDES):
        rng = np.random.default_rng(1000 * trial + k)
        cmd = ctrl.arm[side]
        cmd.mode = MODES[(trial + k) % 3] if trial % 4 else "cart"
        cmd.pose = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(0.5, 0.3, 3))
        cmd.twist = 0.2 * rng.normal(size=6)
        stiffness = np.array(DEFAULT_CART_STIFFNESS)
        if trial % 11 == 5:  # a zero stiffness: the general double diagonalisation
            stiffness[rng.integers(6)] = 0.0
        cmd.stiffness = stiffness
        cmd.posture = rng.normal(size=7)
        cmd.q = rng.normal(size=7)
        cmd.qd = rng.normal(size=7)
        cmd.joint_stiffness = 200.0 if trial % 5 else 300.0 * rng.random(7)
        held = trial % 3 != 0  # a third of the trials hold nothing
        ctrl.payload[side] = (
            Payload(float(2.0 * rng.random()), tuple(0.1 * rng.normal(size=3))) if held else NO_PAYLOAD
        )
    ctrl.torso_q, ctrl.torso_qd = 0.3, 0.1


def test_the_compiled_law_computes_what_the_python_law_computes() -> None:
    """300 random states (joints anywhere within their limits, velocities up to ≈ 5 rad/s:
    bands, velocity braking, rate limits all active at times): torques, the torso's, the
    Cartesian error, the grip pose and the rate-limit state agree to 1e-6 (N·m, m): 1e-8 of
    the 100 N·m torque limit; the two laws round differently where they order the operations
    differently (Eigen's products in C++, numpy's in Python)."""
    reference, law = VelmaController(RobotModel()), CompiledController(RobotModel())
    model = reference.robot.model
    rng = np.random.default_rng(7)
    for trial in range(300):
        q = pin.randomConfiguration(model)
        v = rng.normal(0.0, 1.5, model.nv)
        for ctrl in (reference, law):
            _command(ctrl, trial)
            if trial % 7 == 3:  # the first cycle: no rate limit
                ctrl._prev_arm, ctrl._prev_torso = None, None
        expected, torso_expected = reference.update(q, v)
        got, torso_got = law.update(q, v)
        diffs = [abs(torso_expected - torso_got)]
        for side in SIDES:
            diffs.append(float(np.abs(expected[side] - got[side]).max()))
            diffs.append(float(np.abs(reference.state[side].error - law.state[side].error).max()))
            grip_ref, grip = reference.state[side].grip, law.state[side].grip
            diffs.append(float(np.abs(grip_ref.homogeneous - grip.homogeneous).max()))
        assert reference._prev_arm is not None and law._prev_arm is not None
        diffs.append(float(np.abs(reference._prev_arm - law._prev_arm).max()))
        assert max(diffs) < 1e-6, (trial, diffs, [reference.arm[s].mode for s in SIDES])


def test_a_safety_limit_change_reaches_the_compiled_law() -> None:
    """``limits`` is read again when it is replaced: with the velocity braking off, a joint
    beyond the velocity limit gets the Python law's torque, not the braked one."""
    reference, law = VelmaController(RobotModel()), CompiledController(RobotModel())
    q = pin.neutral(reference.robot.model) + 0.5
    v = np.zeros(reference.robot.model.nv)
    v[reference.arm_slice["right"]] = 3.0  # beyond 2 rad/s
    braked = []
    for limits in (SafetyLimits(), SafetyLimits(arm_velocity=np.inf)):
        for ctrl in (reference, law):
            ctrl.limits = limits
            ctrl._prev_arm = None
            _command(ctrl, 0)
        expected, _ = reference.update(q, v)
        got, _ = law.update(q, v)
        np.testing.assert_allclose(got["right"], expected["right"], atol=1e-9)
        braked.append(got["right"].copy())
    assert np.abs(braked[0] - braked[1]).max() > 1.0  # the braking did act, then did not


def test_an_unknown_mode_is_refused_as_the_python_law_refuses_it() -> None:
    law = CompiledController(RobotModel())
    law.arm["left"].mode = "cartesian"
    q = pin.neutral(law.robot.model)
    with pytest.raises(ValueError, match="left arm: unknown mode 'cartesian'"):
        law.update(q, np.zeros(law.robot.model.nv))


def test_the_robot_moves_the_same_with_either_law(monkeypatch: pytest.MonkeyPatch) -> None:
    """Closed loop: the kitchen's runtime from the same start, both arms holding a Cartesian
    pose 2 cm off where they are, 300 cycles (0.3 s of free-space motion, no contact): the
    joint trajectories agree to 1e-6 rad."""
    finals = []
    for choice in ("python", "compiled"):
        monkeypatch.setenv(ENV_LAW, choice)
        rt = Runtime(seed=0)
        assert isinstance(rt.ctrl, CompiledController) == (choice == "compiled")
        lift_both_arms(rt)
        start = rt.q().copy()
        for _ in range(300):
            rt.cycle()
        finals.append(rt.q().copy())
    moved = np.abs(finals[0] - start).max()
    assert moved > 1e-3  # the arms did move
    np.testing.assert_allclose(finals[1], finals[0], atol=1e-6)


def test_make_controller_follows_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    robot = RobotModel()
    monkeypatch.setenv(ENV_LAW, "python")
    assert type(make_controller(robot)) is VelmaController
    monkeypatch.setenv(ENV_LAW, "compiled")
    assert isinstance(make_controller(robot), CompiledController)
    monkeypatch.delenv(ENV_LAW)
    assert isinstance(make_controller(robot), CompiledController)
    monkeypatch.setenv(ENV_LAW, "fast")
    with pytest.raises(ValueError, match="ROCO_CONTROL_LAW='fast'"):
        make_controller(robot)


def test_without_the_extension_the_python_law_runs_or_the_request_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """As on a machine where no C++ compiler built the extension."""
    robot = RobotModel()
    monkeypatch.setattr(compiled, "_impedance", None)
    monkeypatch.setattr(compiled, "_IMPORT_ERROR", "no module named velma.control._impedance")
    monkeypatch.delenv(ENV_LAW, raising=False)
    with caplog.at_level("WARNING"):
        assert type(make_controller(robot)) is VelmaController
    assert "running the Python law" in caplog.text
    monkeypatch.setenv(ENV_LAW, "compiled")
    with pytest.raises(RuntimeError, match="not built"):
        make_controller(robot)
