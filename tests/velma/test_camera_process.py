"""ag_ex's camera in a process of its own (velma/executor/camera_process.py) and the delivery
thread that warms and rests it (velma/executor/delivery.py)."""

from __future__ import annotations

import math
import os
import queue
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.machine import needs_gl
from velma.executor.camera import CameraWork, Perceived
from velma.executor.camera_process import DEFAULT_IDLE_S, CameraProcess, CameraSpec, camera_idle_s
from velma.executor.capture import WorldCapture
from velma.executor.delivery import ResultDelivery
from velma.model.scene import N_PARTICLES, initial_state, load_kitchen

SPEC = CameraSpec(seed=0, pose_seed=None, noise_seed=0, record=True)


@pytest.fixture(scope="module")
def capture() -> WorldCapture:
    model = load_kitchen(N_PARTICLES, SPEC.seed, SPEC.pose_seed)
    return WorldCapture.of(("jar", "bowl"), 0.0, initial_state(model, settle_steps=50).qpos.copy())


@pytest.fixture(scope="module")
def in_thread(capture: WorldCapture) -> list[Perceived]:
    """The first and second Observe of the same kitchen in this process."""
    work = CameraWork(load_kitchen(N_PARTICLES, SPEC.seed, SPEC.pose_seed), None, SPEC.noise_seed, True)
    try:
        return [work.perceive(capture), work.perceive(capture)]
    finally:
        work.close()


@needs_gl
def test_the_child_sees_what_the_same_work_sees_in_process_and_a_new_child_starts_the_noise_again(
    capture: WorldCapture, in_thread: list[Perceived]
) -> None:
    cam = CameraProcess(SPEC)
    try:
        first = cam.perceive(capture)
        assert cam.starts == 1 and cam.pid is not None and cam.pid != os.getpid()
        assert isinstance(first.observation, Observation)
        assert first.observation == in_thread[0].observation
        assert first.records is not None and {r["object"] for r in first.records} == {"jar", "bowl"}
        second = cam.perceive(capture)
        assert second.observation == in_thread[1].observation
        assert second.observation != first.observation  # the next draws: other noise
        cam.rest()
        assert cam.pid is None
        again = cam.perceive(capture)  # a new child: the sequence starts again
        assert cam.starts == 2
        assert again.observation == in_thread[0].observation
    finally:
        cam.close()
    assert cam.pid is None


@needs_gl
def test_a_child_that_dies_fails_that_observe_and_the_next_one_starts_anew(capture: WorldCapture) -> None:
    cam = CameraProcess(SPEC)
    try:
        cam.warm()
        pid = cam.pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        lost = cam.perceive(capture)
        assert lost.observation is None
        assert lost.reason is not None and "the camera process ended" in lost.reason
        assert "-9" in lost.reason
        got = cam.perceive(capture)
        assert isinstance(got.observation, Observation) and cam.starts == 2
    finally:
        cam.close()


def test_a_kitchen_that_cannot_be_built_answers_with_its_reason(capture: WorldCapture) -> None:
    cam = CameraProcess(CameraSpec(seed=0, pose_seed=None, noise_seed=0, size=(4000, 3000)))
    try:
        got = cam.perceive(capture)
        assert got.observation is None
        assert got.reason is not None
        assert got.reason.startswith("perception error: the camera could not be built")
        assert "off-screen buffer" in got.reason
    finally:
        cam.close()


def test_camera_idle_s_reads_the_environment() -> None:
    assert camera_idle_s({}) == DEFAULT_IDLE_S == camera_idle_s({"ROCO_CAMERA_IDLE_S": " "})
    assert camera_idle_s({"ROCO_CAMERA_IDLE_S": "2.5"}) == 2.5
    assert camera_idle_s({"ROCO_CAMERA_IDLE_S": "never"}) == math.inf
    for bad in ("0", "-1", "soon", "inf", "nan"):
        with pytest.raises(ValueError, match="ROCO_CAMERA_IDLE_S"):
            camera_idle_s({"ROCO_CAMERA_IDLE_S": bad})


class _Host:
    """A camera host that records what the delivery thread asks of it."""

    def __init__(self) -> None:
        self.calls: queue.SimpleQueue[str] = queue.SimpleQueue()

    def warm(self) -> None:
        self.calls.put("warm")

    def perceive(self, capture: WorldCapture) -> Perceived:
        self.calls.put("perceive")
        return Perceived(reason="perception error: test")

    def rest(self) -> None:
        self.calls.put("rest")

    def close(self) -> None:
        self.calls.put("close")


def test_the_delivery_warms_at_start_rests_when_idle_and_warms_again_on_the_next_result(
    capture: WorldCapture,
) -> None:
    host = _Host()
    delivered: queue.SimpleQueue[CommandResult | Observation] = queue.SimpleQueue()
    d: ResultDelivery[int] = ResultDelivery(lambda _t, r: delivered.put(r), host, rest_after_s=0.05)
    try:
        assert host.calls.get(timeout=10) == "warm"
        assert host.calls.get(timeout=10) == "rest"  # nothing came for 0.05 s
        done = CommandResult(command="wait", ok=True, sim_time=1.0)
        d.put(1, done)
        assert host.calls.get(timeout=10) == "warm"  # a command ended: a task runs
        assert delivered.get(timeout=10) is done
        assert host.calls.get(timeout=10) == "rest"
        d.put(2, capture)
        d.put(3, capture)
        failed = delivered.get(timeout=10)
        assert isinstance(failed, CommandResult) and not failed.ok
        assert failed.reason == "perception error: test"
        assert failed.command == "observe" and failed.sim_time == capture.stamp
        assert isinstance(delivered.get(timeout=10), CommandResult)
    finally:
        d.close()
    calls = []
    while not host.calls.empty():
        calls.append(host.calls.get())
    assert [c for c in calls if c == "perceive"] == ["perceive", "perceive"] and calls[-1] == "close"


def test_a_delivery_without_rest_never_rests() -> None:
    host = _Host()
    gate = threading.Event()
    d: ResultDelivery[int] = ResultDelivery(lambda _t, _r: gate.set(), host)
    try:
        assert host.calls.get(timeout=10) == "warm"
        d.put(1, CommandResult(command="wait", ok=True, sim_time=0.0))
        assert gate.wait(10)
    finally:
        d.close()
    assert [host.calls.get(timeout=10)] == ["close"] and host.calls.empty()


MAIN_IMPORTS_MUJOCO = """
import sys
from velma.model.scene import N_PARTICLES, initial_state, load_kitchen  # imports MuJoCo, no MUJOCO_GL
from velma.executor.camera_process import CameraProcess, CameraSpec
from velma.executor.capture import WorldCapture

if __name__ == "__main__":
    model = load_kitchen(N_PARTICLES, 0, None)
    capture = WorldCapture.of(("jar",), 0.0, initial_state(model, settle_steps=0).qpos.copy())
    cam = CameraProcess(CameraSpec(seed=0, pose_seed=None, noise_seed=0))
    try:
        got = cam.perceive(capture)
    finally:
        cam.close()
    print(got.reason or "seen: " + ",".join(o.name for o in got.observation.objects))
"""


@needs_gl
def test_the_child_has_a_gl_platform_when_the_parent_main_module_imported_mujoco(tmp_path: Path) -> None:
    """A spawned child imports the parent's main module before its target runs: one that
    imports MuJoCo must not leave the child's renderer without MUJOCO_GL."""
    script = tmp_path / "observe_once.py"
    script.write_text(MAIN_IMPORTS_MUJOCO)
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2])
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=180, env=env, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "seen: jar", done.stdout[-500:]


class _BrokenHost(_Host):
    """A host whose every call raises (a process that cannot be started)."""

    def warm(self) -> None:
        raise OSError("no more processes")

    def perceive(self, capture: WorldCapture) -> Perceived:
        raise OSError("no more processes")


def test_a_host_that_raises_fails_the_observe_and_the_delivery_goes_on(capture: WorldCapture) -> None:
    delivered: queue.SimpleQueue[CommandResult | Observation] = queue.SimpleQueue()
    d: ResultDelivery[int] = ResultDelivery(lambda _t, r: delivered.put(r), _BrokenHost())
    try:
        d.put(1, capture)
        d.put(2, CommandResult(command="wait", ok=True, sim_time=0.0))
        failed = delivered.get(timeout=10)
        assert isinstance(failed, CommandResult) and not failed.ok
        assert failed.reason == "perception error: no more processes"
        after = delivered.get(timeout=10)
        assert isinstance(after, CommandResult) and after.command == "wait"
    finally:
        d.close()
