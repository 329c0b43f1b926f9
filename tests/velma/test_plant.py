"""The compiled plant (velma/executor/plant.py, velma/control/_plant.hpp) does what the Python
cycle does: the same simulated motion bit for bit, the same contact scans, the same robot
state numbers; and a runtime says why it runs without it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tests.support.arms import lift_both_arms
from velma.control.compiled import ENV_LAW, CompiledController, make_controller
from velma.control.joints import SIDES
from velma.control.mujoco_side import ENV_PLANT, plant_choice
from velma.control.robot_model import RobotModel
from velma.executor import plant as plant_module
from velma.executor.gather import raw_state
from velma.executor.handoff import LatestValue
from velma.executor.plant import plant_unavailable
from velma.executor.runtime import Runtime
from velma.executor.state import raw_layout
from velma.executor.state_block import StateReader, StateWriter, state_values

pytestmark = pytest.mark.skipif(
    plant_unavailable(make_controller(RobotModel())) is not None, reason="the compiled plant is not built"
)

# the left wrist bent into its own hand (tests/velma/test_self_collision.py): robot–robot contacts
TOUCHING = {5: -0.52, 6: 0.37}


def _move(rt: Runtime) -> None:
    """Both arms to a Cartesian pose 2 cm above where they are, the right hand closing."""
    lift_both_arms(rt)
    rt.hands.command("right", 1.0)


def test_the_robot_moves_the_same_with_the_compiled_plant() -> None:
    """The kitchen from the same start, the same commands, 300 cycles with and without the
    compiled plant (both with the compiled law): qpos, qvel, the controls, the controller's
    grip poses and the contact scans are equal bit for bit."""
    runs = []
    for compiled in (True, False):
        rt = Runtime(seed=0, compiled_plant=compiled)
        assert (rt.plant is not None) == compiled
        start = rt.data.qpos.copy()
        _move(rt)
        for _ in range(300):
            rt.cycle()
        runs.append(rt)
    with_plant, without = runs
    assert np.abs(with_plant.data.qpos - start).max() > 1e-3  # the robot did move
    np.testing.assert_array_equal(with_plant.data.qpos, without.data.qpos)
    np.testing.assert_array_equal(with_plant.data.qvel, without.data.qvel)
    np.testing.assert_array_equal(with_plant.data.ctrl, without.data.ctrl)
    for side in SIDES:
        assert with_plant.grip(side) == without.grip(side)
        assert with_plant.touch[side] == without.touch[side]
    assert with_plant.cycles == without.cycles == 300


def _jar_in_right_hand(rt: Runtime) -> None:
    """The jar moved so that its origin is at the right grip site (fingers open around it)."""
    mujoco.mj_forward(rt.model, rt.data)
    delta = rt.data.site_xpos[rt.grip_site["right"]] - rt.data.xpos[rt.model.body("jar").id]
    rt.displace("jar", (float(delta[0]), float(delta[1]), float(delta[2])))


def test_the_servos_step_as_the_python_servos_do() -> None:
    """The right hand closing on the jar (its clutches break away and the proximal setpoints
    ratchet), the left hand spreading, the head turning: 1300 cycles with and without the
    compiled plant step the hands' setpoints, the head's and the whole simulation alike, bit
    for bit."""
    runs = []
    for compiled in (True, False):
        rt = Runtime(seed=0, compiled_plant=compiled)
        _jar_in_right_hand(rt)
        rt.hands.command("right", 2.0)
        rt.hands.command("left", 0.6, spread=0.5)
        rt.head_target = rt.head_set + np.array([0.3, -0.2])
        broke_at = None
        for k in range(1300):
            rt.cycle()
            if broke_at is None and rt.hands.broken_away("right").any():
                broke_at = k
        runs.append((rt, broke_at))
    (with_plant, broke), (without, broke_py) = runs
    assert broke is not None and broke == broke_py  # the clutch did break away, in both
    np.testing.assert_array_equal(with_plant.hands.state, without.hands.state)
    np.testing.assert_array_equal(with_plant.head, without.head)
    np.testing.assert_array_equal(with_plant.data.ctrl, without.data.ctrl)
    np.testing.assert_array_equal(with_plant.data.qpos, without.data.qpos)
    assert with_plant.hands.set["left"].steady and without.hands.set["left"].steady
    assert not with_plant.hands.set["right"].steady  # a broken-away hand keeps stepping


def test_the_contact_scans_are_the_python_scans() -> None:
    """The jar moved into the right hand and the left wrist bent into its hand: the compiled
    scans report the hand–jar and the robot–robot contacts exactly as ContactMonitor does."""
    rt = Runtime(seed=0, compiled_plant=True)
    assert rt.plant is not None
    jar = rt.model.body("jar").id
    mujoco.mj_forward(rt.model, rt.data)
    palm = rt.data.xpos[rt.model.body("right_HandPalmLink").id]
    _jar_in_right_hand(rt)
    for k, value in TOUCHING.items():
        rt.data.qpos[rt.model.joint(f"left_arm_{k}_joint").qposadr[0]] = value
    mujoco.mj_forward(rt.model, rt.data)
    assert np.linalg.norm(palm - rt.data.xpos[rt.model.body("right_HandPalmLink").id]) < 1e-9
    for side in SIDES:
        assert rt.plant.touching(side) == rt.contacts.touching(rt.data, side)
    assert jar in rt.plant.touching("right")
    pairs = rt.plant.self_contacts()
    assert pairs and pairs == rt.contacts.self_contacts(rt.data)


def test_the_state_numbers_are_the_python_numbers() -> None:
    """After cycles in Cartesian mode (a setpoint to report), raw_state with the compiled
    gather is raw_state with the Python gather, byte for byte."""
    rt = Runtime(seed=0, compiled_plant=True)
    assert rt.plant is not None
    _move(rt)
    for _ in range(20):
        rt.cycle()
    compiled = raw_state(rt)
    plant, rt.plant = rt.plant, None
    try:
        python = raw_state(rt)
    finally:
        rt.plant = plant
    assert compiled == python
    assert np.frombuffer(compiled.values)[raw_layout(len(rt.joint_v_index))[2]] == 1.0  # a setpoint


def test_the_published_state_is_the_python_state() -> None:
    """The robot state that the compiled plant publishes into the shared block is, byte for
    byte, what the Python writer publishes; the reader pairs it with its names, and a new
    grasp moves the names' version so the next read carries the new words."""
    rt = Runtime(seed=0, compiled_plant=True)
    assert rt.plant is not None
    _move(rt)
    for _ in range(20):
        rt.cycle()
    blocks = [LatestValue.create(4096) for _ in range(4)]
    try:
        compiled = StateWriter(rt, blocks[0], blocks[1])
        python = StateWriter(rt, blocks[2], blocks[3], compiled=False)
        assert compiled.compiled and not python.compiled
        for writer in (compiled, python):
            writer.publish("a test hold")
        assert blocks[0].read() == blocks[2].read()
        assert blocks[0].read() == state_values(rt, 1).tobytes()
        read = StateReader(blocks[0], blocks[1]).read()
        reference = raw_state(rt, "a test hold")
        assert read == reference
        rt.held["left"] = rt.model.body("jar").id
        compiled.publish(None)
        read = StateReader(blocks[0], blocks[1]).read()
        assert compiled.version == 2 and read is not None
        assert read.held_object == (None, "jar") and read.holding is None
        compiled.publish(None)
        assert compiled.version == 2  # the same words: not written again
        compiled.close()
    finally:
        for block in blocks:
            block.close()
            block.unlink()


def test_a_runtime_says_why_it_runs_the_python_cycle(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Python law, or MuJoCo of another version than the headers the module was built
    with: no plant, with the reason; asked for one anyway, the runtime raises."""
    monkeypatch.setenv(ENV_LAW, "python")
    assert plant_unavailable(make_controller(RobotModel())) == "the Python law runs"
    with pytest.raises(RuntimeError, match="the Python law runs"):
        Runtime(seed=0, compiled_plant=True)
    monkeypatch.setenv(ENV_LAW, "compiled")
    ctrl = make_controller(RobotModel())
    assert isinstance(ctrl, CompiledController) and plant_unavailable(ctrl) is None
    monkeypatch.setattr(plant_module.mujoco, "mj_version", lambda: 1)
    assert "running MuJoCo 1" in (plant_unavailable(ctrl) or "")


def test_the_plant_takes_only_arrays_it_can_write_through() -> None:
    """An array the plant would have to convert (float32, or a strided view) is refused:
    the cycle must write into the controller's own arrays, never into a silent copy."""
    rt = Runtime(seed=0, compiled_plant=True)
    assert rt.plant is not None and isinstance(rt.ctrl, CompiledController)
    native = rt.plant._plant
    with pytest.raises(TypeError):
        rt.ctrl.bind_plant(native, np.zeros(33, dtype=np.float32), rt.plant.v, rt.plant.parts)
    with pytest.raises(TypeError):
        rt.ctrl.bind_plant(native, rt.plant.q, np.zeros(66)[::2], rt.plant.parts)
    with pytest.raises(ValueError, match="wrong size"):
        rt.ctrl.bind_plant(native, rt.plant.q, rt.plant.v, np.zeros(3))


def test_roco_plant_chooses_the_cycle(monkeypatch: pytest.MonkeyPatch) -> None:
    """ROCO_PLANT=python runs the Python cycle, compiled the compiled one; unset, the compiled
    one where it can run; another value is an error."""
    assert plant_choice({}) is None
    monkeypatch.delenv(ENV_PLANT, raising=False)
    assert Runtime(seed=0).plant is not None
    monkeypatch.setenv(ENV_PLANT, "python")
    assert Runtime(seed=0).plant is None
    monkeypatch.setenv(ENV_PLANT, "compiled")
    assert Runtime(seed=0).plant is not None
    with pytest.raises(ValueError, match="ROCO_PLANT='fast'"):
        plant_choice({ENV_PLANT: "fast"})
