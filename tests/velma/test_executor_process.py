"""ag_ex's executor with its control loop in a process of its own (velma/executor/process.py):
results cross back, the state and timing are readable, holding ends commands and keeps the
hands, a dead loop process fails open commands, and stop answers what is queued."""

from __future__ import annotations

import os
import queue
import signal
import time
from collections.abc import Iterator

import numpy as np
import pytest

from shared.fipa_codec.languages.l_ex import Arm, CommandResult, Grasp, MoveJoints, Observe, Wait
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.hold import Hold
from velma.control.compiled import compiled_available
from velma.executor import ExecutorProcess
from velma.executor.loop import ControlLoop
from velma.executor.runtime import Runtime
from velma.executor.state import RobotSnapshot
from velma.rotations import quat_wxyz

Result = CommandResult | Observation


@pytest.fixture(scope="module")
def ex() -> Iterator[ExecutorProcess]:
    e = ExecutorProcess(realtime=False)
    e.start()
    yield e
    e.stop()


def _submit(ex: ExecutorProcess, command: object) -> queue.SimpleQueue[Result]:
    out: queue.SimpleQueue[Result] = queue.SimpleQueue()
    ex.submit(command, out.put)  # type: ignore[arg-type]
    return out


def _state_after(ex: ExecutorProcess, sim_time: float) -> RobotSnapshot:
    """The first state the loop published after ``sim_time`` (s; a result's time is that of the
    cycle's start, a state published at that time is older than the result): the state is
    rewritten every STATE_PERIOD cycles, so one read right after a result can still be older
    than it and say what an earlier test left. Gives up after 10 s of wall time."""
    deadline = time.monotonic() + 10.0
    snap = ex.snapshot()
    while (snap is None or snap.sim_time <= sim_time) and time.monotonic() < deadline:
        snap = ex.snapshot()
    assert snap is not None and snap.sim_time > sim_time, "the loop published no state after the result"
    return snap


@pytest.mark.requirement("R3.1")
def test_commands_cross_and_state_is_published(ex: ExecutorProcess) -> None:
    assert ex.pid is not None and ex.pid != os.getpid()
    r = _submit(ex, Wait(duration=0.2)).get(timeout=60)
    assert isinstance(r, CommandResult) and r.ok and r.sim_time >= 0.2
    obs = _submit(ex, Observe(objects=("jar", "bowl"))).get(timeout=60)
    assert isinstance(obs, Observation)
    assert {o.name for o in obs.objects} >= {"jar", "bowl"}
    snap = _state_after(ex, r.sim_time)
    assert len(snap.joints) == 33 and snap.holding is None
    assert snap.timing is not None and snap.timing.cycles >= 200 and snap.timing.pacing == "fast"
    assert ex.setup is not None and ex.setup.notes == ("not requested",)
    # the timing on its own (ag_ex_timing.json) takes its simulation time from the same state
    assert ex.timing().sim_time >= snap.sim_time
    assert {p.name for p in snap.timing.parts} == {"primitive", "control", "physics", "hand-offs"}
    # which impedance law the loop ran (velma/control/compiled.py), for the report
    assert ex.timing().control_law == ("compiled" if compiled_available() else "python")
    assert ex.timing().plant in ("compiled", "python")


def test_bad_command_is_answered_and_loop_goes_on(ex: ExecutorProcess) -> None:
    r = _submit(ex, MoveJoints(positions={"no_such_joint": 0.0}, duration=1.0)).get(timeout=60)
    assert isinstance(r, CommandResult) and not r.ok and r.reason == "unknown joint: no_such_joint"
    assert _submit(ex, Wait(duration=0.01)).get(timeout=60).ok  # type: ignore[union-attr]


def test_a_command_the_loop_s_process_does_not_know_is_answered_and_loop_goes_on(ex: ExecutorProcess) -> None:
    """A command with no row of L_EX ``COMMANDS`` in the loop's process (tests/support/hold.py's
    ``Hold``, registered nowhere: the loop's process imports only what its own modules import)
    fails by name, and the loop goes on."""
    r = _submit(ex, Hold(duration=0.01)).get(timeout=60)
    assert isinstance(r, CommandResult) and not r.ok, r
    assert r.command == "hold" and r.reason == "not an executor command in the loop's process: hold", r
    assert _submit(ex, Wait(duration=0.01)).get(timeout=60).ok  # type: ignore[union-attr]


def test_the_loop_reports_each_start_and_end_before_the_result(ex: ExecutorProcess) -> None:
    """``on_start`` and ``on_end`` (ag_ex's ledger, velma/executor/ledger.py) are called for
    the commands the loop runs, in simulated time, before ``on_done``; a command cancelled
    while queued ends without a start."""
    events: queue.SimpleQueue[tuple[object, ...]] = queue.SimpleQueue()
    ex.on_start = lambda token, name, t: events.put(("start", token, name, t))
    ex.on_end = lambda token, name, t, outcome, result: events.put(("end", token, name, t, outcome, result))
    try:
        running = ex.submit(Wait(duration=0.1), lambda _r: events.put(("done", running)))
        queued = ex.submit(Wait(duration=5.0), lambda _r: events.put(("done", queued)))
        assert ex.cancel(queued)
        got = [events.get(timeout=60) for _ in range(5)]
        mine = [e for e in got if e[1] == running]
        assert [e[0] for e in mine] == ["start", "end", "done"]
        (_, _, name, start), (_, _, name_end, end, outcome, _result) = mine[0], mine[1]
        assert (name, name_end, outcome) == ("wait", "wait", "ok")
        assert isinstance(mine[1][5], CommandResult) and mine[1][5].ok  # the result, for the ledger
        assert isinstance(start, float) and isinstance(end, float) and end >= start + 0.1 - 1e-9  # float sums
        halted = [e for e in got if e[1] == queued]
        assert [e[0] for e in halted] == ["end", "done"] and halted[0][4] == "failure: halted"
    finally:
        ex.on_start = ex.on_end = None


def test_a_replayed_result_is_answered_in_order_and_the_loop_does_not_run_it(ex: ExecutorProcess) -> None:
    """``replay`` (ag_ex's answer from its ledger) answers with the result it is given, and
    the loop starts nothing for it."""
    starts: queue.SimpleQueue[str] = queue.SimpleQueue()
    ex.on_start = lambda _token, name, _t: starts.put(name)
    try:
        assert _submit(ex, Wait(duration=0.05)).get(timeout=60).ok  # type: ignore[union-attr]
        kept = CommandResult(command="grasp", ok=False, reason="no contact", sim_time=4.0)
        out: queue.SimpleQueue[Result] = queue.SimpleQueue()
        ex.replay("grasp", kept, out.put)
        assert out.get(timeout=60) == kept
        assert _submit(ex, Wait(duration=0.05)).get(timeout=60).ok  # type: ignore[union-attr]
        assert [starts.get(timeout=10), starts.get(timeout=10)] == ["wait", "wait"] and starts.empty()
    finally:
        ex.on_start = None


def test_hold_ends_commands_and_says_so(ex: ExecutorProcess) -> None:
    long = _submit(ex, Wait(duration=1000.0))
    queued = _submit(ex, Wait(duration=1.0))
    assert ex.hold("a_ta lost")
    ended = [q.get(timeout=60) for q in (long, queued)]
    results = [r for r in ended if isinstance(r, CommandResult)]
    assert [(r.ok, r.reason) for r in results] == [(False, "held: a_ta lost")] * 2, ended
    snap = _state_after(ex, max(r.sim_time for r in results))
    assert snap.holding == "a_ta lost"
    assert _submit(ex, Wait(duration=0.01)).get(timeout=60).ok  # type: ignore[union-attr]


def test_dead_loop_fails_open_commands() -> None:
    e = ExecutorProcess(realtime=False)
    e.start()
    try:
        pending = _submit(e, Wait(duration=1000.0))
        assert e.pid is not None
        os.kill(e.pid, signal.SIGKILL)
        r = pending.get(timeout=60)
        assert isinstance(r, CommandResult) and not r.ok and "exited" in (r.reason or "")
        late = _submit(e, Wait(duration=0.1)).get(timeout=10)
        assert isinstance(late, CommandResult) and not late.ok and "not running" in (late.reason or "")
    finally:
        e.stop()


def test_stop_answers_queued_commands() -> None:
    e = ExecutorProcess(realtime=False)
    e.start()
    pending = [_submit(e, Wait(duration=1000.0)) for _ in range(3)]
    e.stop()
    for q in pending:
        r = q.get(timeout=10)
        assert isinstance(r, CommandResult) and r.reason == "stopped"
    assert not e.alive


def test_hold_keeps_the_hands_and_the_arms_still() -> None:
    """While a grasp closes the fingers, holding ends it but does not open the hand; the arms
    then stay where they are in joint impedance (under gravity)."""
    rt = Runtime()
    loop: ControlLoop[int] = ControlLoop(rt)
    loop.submit(1, Grasp(arm=Arm.RIGHT, spread=0.0))
    for _ in range(400):
        assert loop.cycle() is None
    closing = rt.hands.proximal(rt.data, "right").copy()
    assert np.all(closing > 0.3)  # the fingers are closing
    ended = loop.hold("a_ta lost")
    assert [(t, r.reason) for t, r in ended] == [(1, "held: a_ta lost")]
    q0 = rt.q().copy()
    for _ in range(1000):
        assert loop.cycle() is None
    assert np.all(rt.hands.proximal(rt.data, "right") >= closing - 0.01)  # not opened
    for side in ("right", "left"):
        sl = rt.ctrl.arm_slice[side]
        assert rt.ctrl.arm[side].mode == "joint"
        assert np.max(np.abs(rt.q()[sl] - q0[sl])) < 0.02
    assert loop.holding == "a_ta lost"


def test_cartesian_setpoint_is_valid_when_the_law_switches_to_it() -> None:
    """MoveTool switches an arm from joint to Cartesian impedance once its IK has converged;
    in that cycle the setpoint is the current grip pose, not a stale (identity) one."""
    from shared.fipa_codec.languages.common import Pose
    from shared.fipa_codec.languages.l_ex import MoveTool

    rt = Runtime()
    loop: ControlLoop[int] = ControlLoop(rt)
    grip = rt.grip("right")
    target = grip.translation + np.array([0.0, 0.0, 0.05])
    w, x, y, z = quat_wxyz(grip.rotation)
    loop.submit(
        1,
        MoveTool(arm=Arm.RIGHT, target=Pose(position=tuple(target), orientation=(w, x, y, z)), duration=1.0),
    )
    assert rt.ctrl.arm["right"].mode == "joint"
    for _ in range(200):
        loop.cycle()
        if rt.ctrl.arm["right"].mode == "cart":
            break
    assert rt.ctrl.arm["right"].mode == "cart"
    assert np.linalg.norm(rt.ctrl.arm["right"].pose.translation - grip.translation) < 0.01
    v = rt.v()[rt.ctrl.arm_slice["right"]]
    assert np.max(np.abs(v)) < 0.5  # no jolt towards the world origin


def test_safe_mode_is_soft_and_gravity_compensated(ex: ExecutorProcess) -> None:
    pending = _submit(ex, Wait(duration=1000.0))
    assert ex.safe("operator")
    r = pending.get(timeout=60)
    assert isinstance(r, CommandResult) and r.reason == "safe mode: operator"
    snap = _state_after(ex, r.sim_time)
    assert snap.holding == "safe mode: operator"
    later = snap
    while later.sim_time < snap.sim_time + 1.0:  # one simulated second in safe mode
        later = ex.snapshot() or later
    drift = max(abs(later.joints[j] - snap.joints[j]) for j in snap.joints if "_arm_" in j)
    assert drift < 0.05  # gravity compensated: the soft arms do not fall
    assert _submit(ex, Wait(duration=0.01)).get(timeout=60).ok  # type: ignore[union-attr]


def test_a_loop_that_cannot_start_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    """The loop process's start-up error reaches ``start``, not only its exit code (here an
    impedance law nobody has: ROCO_CONTROL_LAW, velma/control/compiled.py)."""
    monkeypatch.setenv("ROCO_CONTROL_LAW", "fast")  # the spawned loop inherits it
    e = ExecutorProcess(realtime=False)
    with pytest.raises(RuntimeError, match=r"did not start: ValueError: ROCO_CONTROL_LAW='fast'"):
        e.start(timeout=120)
