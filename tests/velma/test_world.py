"""The world as a process of its own (velma/world/): a controller commands it over the robot
link in lockstep; when the controller stops, the safety layer holds the robot and the world
goes on; a controller that attaches again finds the world as it is now, never rolled back."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from velma.control.compiled import make_controller
from velma.control.hand import HAND_WIDTH, TARGET
from velma.control.joints import HEAD_JOINTS, SIDES, TORSO_JOINT, arm_joints
from velma.control.mujoco_side import mujoco_side_unavailable
from velma.control.robot_model import RobotModel
from velma.executor.checkpoint import observe_scene
from velma.shm import SHM_DIR
from velma.world.files import FINAL_FILE, link_name
from velma.world.hardware import CONTACT_PERIOD, DT, SimulatedVelma
from velma.world.layout import COMMAND, HAND_KEEP, HAND_MOVE, HAND_OP, MEASURED
from velma.world.link import RobotLink
from velma.world.serve import HOLD_CYCLES

HELD = [RobotModel().v_index(j) for j in (*arm_joints("right"), *arm_joints("left"), TORSO_JOINT)]
"""The arm and torso joints in the link's order: those the safety layer holds."""
TURN = 0.3
"""How far (rad) the controller turns the torso from where it stands."""


class Controller:
    """The impedance law (velma/control/) on the link: joint setpoints at the measured pose,
    the torso's turned by ``turn``; the hands and the head keep their targets."""

    def __init__(self, name: str, turn: float = 0.0) -> None:
        self.link = RobotLink.attach(name)
        self.measured, self.command = np.zeros(MEASURED.size), np.zeros(COMMAND.size)
        assert self.link.wait_measured(0, 30.0, spin_s=0.0), "the world published nothing"
        self.k = self.link.read_measured(self.measured)
        assert self.k is not None
        robot = RobotModel()
        self.ctrl = make_controller(robot, DT)
        self.head = [robot.v_index(j) for j in HEAD_JOINTS]
        q, v = self.q(), self.measured[MEASURED.slice("v")].copy()
        for s in SIDES:
            self.ctrl.arm[s].q = q[self.ctrl.arm_slice[s]].copy()
        self.ctrl.torso_q = float(q[self.ctrl.torso_idx]) + turn
        self.ctrl.kinematics(q, v)
        self.command[COMMAND.slice("hand")] = (
            0.0  # sequence 0: no hand command, the servos keep their targets
        )

    def q(self) -> np.ndarray:
        return self.measured[MEASURED.slice("q")].copy()

    @property
    def time(self) -> float:
        return float(self.measured[MEASURED.fields["time"][0]])

    @property
    def holding(self) -> bool:
        return bool(self.measured[MEASURED.fields["holding"][0]])

    def run(self, cycles: int) -> list[int]:
        """Command ``cycles`` cycles in lockstep; per command, how many cycles the world was
        ahead of it when the controller read the next state (the world steps with the
        command of the state before: at most 2)."""
        ahead = []
        for _ in range(cycles):
            taus, tau_torso = self.ctrl.update(self.q(), self.measured[MEASURED.slice("v")].copy())
            self.command[COMMAND.slice("tau")] = np.concatenate([taus["right"], taus["left"], [tau_torso]])
            self.command[COMMAND.slice("head")] = self.q()[self.head]
            answered = self.k
            self.link.command(answered, self.command)
            assert self.link.wait_measured(answered + 1, 10.0, spin_s=0.0), "the world stopped"
            self.k = self.link.read_measured(self.measured)
            assert self.k is not None
            ahead.append(self.k - answered)
        return ahead

    def close(self) -> None:
        self.link.close()


def test_a_controller_that_ends_leaves_the_robot_held_and_the_next_finds_the_world_as_it_is(
    world: str,
) -> None:
    first = Controller(world, turn=TURN)
    start = first.q()
    first.run(HOLD_CYCLES)  # attached to a world that runs on the wall clock: it leaves the hold
    ahead = first.run(1500)  # 1.5 s of the torso's turn, in lockstep
    assert not first.holding
    assert max(ahead) <= 2  # the world never ran ahead of its commands: no step without one
    torso = first.ctrl.torso_idx
    assert first.q()[torso] - start[torso] > 0.1  # it turned
    last_q, last_time, last_k = first.q(), first.time, first.k
    first.close()  # the controller ends, mid-motion

    second = Controller(world)
    # the world steps once more with the last command it had, waits LOCKSTEP_WAIT_S for the
    # next one, then steps on, held
    assert second.link.wait_measured(last_k + 2, 10.0, spin_s=0.0)
    second.k = second.link.read_measured(second.measured)
    held_at = second.time
    assert second.holding and held_at > last_time  # the world went on without a controller …
    assert np.abs(second.q()[HELD] - last_q[HELD]).max() < 0.02  # … holding the robot where it was
    assert second.link.wait_measured(second.k + 300, 10.0, spin_s=0.0)
    second.link.read_measured(second.measured)
    assert second.time >= held_at + 0.299  # on the wall clock, 1 ms a cycle
    assert np.abs(second.q()[HELD] - last_q[HELD]).max() < 0.02  # still held: nothing fell
    # commanded again, the hold ends: at the first command that answers the state before in
    # time (the held world steps on the wall clock, 1 ms a cycle)
    for _ in range(1000):
        second.run(1)
        if not second.holding:
            break
    assert not second.holding
    second.close()


def test_the_safety_layer_holds_the_arms_against_gravity() -> None:
    sim = SimulatedVelma()
    measured = np.zeros(MEASURED.size)
    sim.measure(measured)
    q0 = measured[MEASURED.slice("q")].copy()
    for _ in range(500):
        sim.apply(None)  # no controller: the brakes
        sim.step()
    sim.measure(measured)
    assert sim.holding and measured[MEASURED.fields["holding"][0]] == 1.0
    assert np.abs(measured[MEASURED.slice("q")][HELD] - q0[HELD]).max() < 1e-3  # without: 1.7 rad


def says(path: Path) -> str:
    """What a file that may be replaced or removed meanwhile holds ("" when absent)."""
    try:
        return path.read_text()
    except FileNotFoundError:
        return ""


def test_python_m_velma_world_serves_the_run_folder_and_cleans_up_on_sigterm(tmp_path: Path) -> None:
    """...and says it is ready (its ready file, a container's health check) while it serves."""
    ready = tmp_path / "world.ready"
    ready.write_text("left by a world that was killed\n")
    world = subprocess.Popen(
        [sys.executable, "-m", "velma.world", "--run-dir", str(tmp_path)],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "ROCO_READY_FILE": str(ready)},
    )
    try:
        deadline = time.monotonic() + 120
        while (name := link_name(tmp_path)) is None and world.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # polls for the file the world writes once its link exists
        assert name is not None, world.stderr.read() if world.poll() is not None and world.stderr else ""
        while not says(ready).startswith("velma.world: serving") and time.monotonic() < deadline:
            time.sleep(0.05)  # written just after the link's name
        assert says(ready).startswith(f"velma.world: serving the robot link {name} ")
        controller = Controller(name)
        controller.run(HOLD_CYCLES)
        controller.close()
        world.send_signal(signal.SIGTERM)
        assert world.wait(30) == 0
    finally:
        if world.poll() is None:
            world.kill()
            world.wait()
    assert link_name(tmp_path) is None and not (SHM_DIR / name).exists() and not ready.exists()
    final = observe_scene((tmp_path / FINAL_FILE).read_bytes())  # the kitchen as the world left it
    sim = SimulatedVelma()
    first = np.zeros(sim.scene_size)
    sim.scene(first)
    start = observe_scene(first.tobytes())
    assert final.stamp > start.stamp
    assert [o.name for o in final.objects] == [o.name for o in start.objects]
    for now, then in zip(final.objects, start.objects, strict=True):  # on the shelf, untouched
        assert now.pose.position == pytest.approx(then.pose.position, abs=2e-3), now.name
    with pytest.raises(ValueError, match="coordinates"):
        observe_scene(bytes(16))


def test_python_m_velma_world_without_a_run_folder_says_so_in_one_line(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "velma.world", "--run-dir", str(tmp_path / "missing")],
        capture_output=True,
        text=True,
        timeout=120,
        env={k: v for k, v in os.environ.items() if not k.startswith("ROCO_")},
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [f"velma.world: no run folder {tmp_path / 'missing'}"]


def test_a_hand_takes_each_operation_once_and_reports_it() -> None:
    """``COMMAND`` ``hand``: an operation is taken when its sequence number changes, however
    often the command repeats it; the measured state says which one the hand took, its servo
    rows, the head's setpoints and the robot touching itself (nothing, standing)."""
    sim = SimulatedVelma()
    measured, command = np.zeros(MEASURED.size), np.zeros(COMMAND.size)
    sim.measure(measured)
    command[COMMAND.slice("tau")] = 0.0
    command[COMMAND.slice("head")] = measured[MEASURED.slice("head")]
    left = COMMAND.fields["hand"][0] + HAND_OP * SIDES.index("left")
    target = HAND_WIDTH * SIDES.index("left") + TARGET
    command[left : left + HAND_OP] = (1.0, HAND_MOVE, 1.0, np.nan)
    for _ in range(3):
        sim.apply(command)
        sim.step()
    sim.measure(measured)
    rows = measured[MEASURED.slice("hand")]
    assert measured[MEASURED.slice("hand_seq")][SIDES.index("left")] == 1.0
    assert rows[target : target + 3].tolist() == [1.0, 1.0, 1.0]
    sim.hands.keep("left")  # the hand changes its targets on its own (as a halt would) …
    sim.apply(command)  # … and the repeated operation 1 is not taken again
    assert sim.hands.set["left"].target.max() < 1.0
    command[left : left + HAND_OP] = (2.0, HAND_KEEP, np.nan, np.nan)
    sim.apply(command)
    assert sim.hand_seq[SIDES.index("left")] == 2.0
    for _ in range(CONTACT_PERIOD):
        sim.step()
        sim.measure(measured)
    assert (measured[MEASURED.slice("self_touch")] == -1.0).all()
    assert measured[MEASURED.slice("head")] == pytest.approx(sim.head_set)


@pytest.mark.skipif(mujoco_side_unavailable() is not None, reason="the compiled plant is not built")
def test_the_compiled_world_cycle_is_the_python_one_bit_for_bit() -> None:
    """``SimulatedVelma`` stepped in C++ and in Python, side by side over 2 s: the safety hold,
    then zero torques (the arms fall onto the robot and the kitchen: tactile and self-contact
    scans that find something), a hand operation, a head move and a disturbance. The measured
    state and the whole scene are equal to the last bit every cycle."""
    compiled, python = SimulatedVelma(compiled=True), SimulatedVelma(compiled=False)
    assert compiled.plant is not None and python.plant is None
    a, b = np.zeros(MEASURED.size), np.zeros(MEASURED.size)
    command = np.zeros(COMMAND.size)
    compiled.measure(a)
    command[COMMAND.slice("head")] = a[MEASURED.slice("head")] + (0.3, -0.2)
    left = COMMAND.fields["hand"][0] + HAND_OP * SIDES.index("left")
    command[left : left + HAND_OP] = (1.0, HAND_MOVE, 1.0, 0.5)
    command[COMMAND.slice("disturb")] = (1.0, compiled.model.body("jar").id, 0.01, 0.0, 0.0, 0.0)
    found = {"touch": 0, "self_touch": 0}
    for k in range(2000):
        for sim, measured in ((compiled, a), (python, b)):
            sim.measure(measured)
            sim.apply(None if k < 50 else command)
            sim.step()
        assert np.array_equal(a, b, equal_nan=True), (k, np.flatnonzero(a != b))
        assert np.array_equal(compiled.data.qpos, python.data.qpos), k
        for field in found:
            found[field] += int((a[MEASURED.slice(field)][0::2] >= 0).sum())
    assert all(found.values()), found  # the scans were compared on contacts, not on empty slots
    assert compiled.hand_seq.tolist() == python.hand_seq.tolist() == [0.0, 1.0]
    assert compiled.disturb_seq == python.disturb_seq == 1.0


def test_roco_plant_chooses_the_world_cycle(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROCO_PLANT", "python")
    assert SimulatedVelma(n_particles=0).plant is None
    monkeypatch.setenv("ROCO_PLANT", "fast")
    with pytest.raises(ValueError, match="ROCO_PLANT"):
        SimulatedVelma(n_particles=0)


@pytest.mark.skipif(mujoco_side_unavailable() is not None, reason="the compiled plant is not built")
def test_the_compiled_world_cycle_refuses_a_vector_shorter_than_the_layout() -> None:
    sim = SimulatedVelma(n_particles=0, compiled=True)
    assert sim.plant is not None
    with pytest.raises(ValueError, match="shorter than the layout"):
        sim.measure(np.zeros(MEASURED.size - 1))
    with pytest.raises(ValueError, match="shorter than the layout"):
        sim.apply(np.zeros(COMMAND.size - 1))


def test_a_controller_that_orders_the_joints_otherwise_than_the_world_is_refused() -> None:
    """The link carries the joints in the world's order (velma/control/joints.py
    ``robot_joints``, Pinocchio's); a controller mapping them otherwise would command the wrong
    joints: it is refused before it waits for the world's state."""
    import mujoco

    from velma.control.joints import JointMap, robot_joints
    from velma.executor.world_link import WorldLink
    from velma.model.scene import load_kitchen

    model = load_kitchen(4)
    link = RobotLink.create(MEASURED.size, COMMAND.size, 1 + model.nq)
    try:
        swapped = JointMap.build(model, robot_joints(model)[::-1])
        with pytest.raises(ValueError, match="orders the robot's joints otherwise"):
            WorldLink(link, model, mujoco.MjData(model), swapped, timeout_s=0.1)
    finally:
        link.close()
