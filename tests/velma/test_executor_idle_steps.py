"""The threaded executor as fast as possible without idle steps (velma/executor/core.py
``idle_steps=False``): a caller that submits each command after the last one's result, slowly
or at once, gets the same results at the same robot times and leaves the kitchen in the same
state, bit for bit. With idle steps the robot time between two commands is whatever the
caller's thread took, and the scripted tidy-up touched the robot itself in some runs under
load (tests/velma/test_velma_kitchen.py)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
import pytest

from shared.fipa_codec.languages.l_ex import TORSO_JOINT, CommandResult, ExecutorCommand, MoveJoints, Observe
from shared.fipa_codec.languages.l_sd import Observation
from velma import scenario as sc
from velma.executor import Executor

COMMANDS: list[ExecutorCommand] = [
    Observe(),
    MoveJoints(positions={TORSO_JOINT: 0.2}, duration=0.3),
    MoveJoints(positions={TORSO_JOINT: 0.0}, duration=0.3),
    Observe(),
]
Result = CommandResult | Observation
Submit = Callable[[ExecutorCommand, Callable[[Result], None]], object]


def _run(slow_caller: bool) -> tuple[list[float], np.ndarray]:
    """The robot times of COMMANDS' results and the kitchen's final qpos and qvel; a slow
    caller submits each command 0.1 s of wall time after the last one's result (a loaded
    machine's test thread, made certain)."""
    ex = Executor(realtime=False, seed=0, perception="truth", idle_steps=False)

    def submit(command: ExecutorCommand, on_done: Callable[[Result], None]) -> object:
        if slow_caller:
            time.sleep(0.1)  # not a synchronisation: the caller's delay under test
        return ex.submit(command, on_done)

    ex.start()
    try:
        results = sc.run_script(submit, COMMANDS, timeout=120)
    finally:
        ex.stop()
    assert len(results) == len(COMMANDS) and all(getattr(r, "ok", True) for r in results), results
    stamps = [r.stamp if isinstance(r, Observation) else r.sim_time for r in results]
    return stamps, np.concatenate([ex.rt.data.qpos, ex.rt.data.qvel])


def test_a_slow_caller_gets_the_same_run() -> None:
    fast_times, fast_state = _run(slow_caller=False)
    slow_times, slow_state = _run(slow_caller=True)
    assert slow_times == fast_times
    assert np.array_equal(slow_state, fast_state)


def test_stop_ends_the_wait_of_an_idle_executor() -> None:
    ex = Executor(realtime=False, seed=0, perception="truth", idle_steps=False)
    ex.start()
    done = threading.Event()
    ex.submit(Observe(), lambda r: done.set())
    assert done.wait(60)  # the loop now waits for a command
    stopping = threading.Thread(target=ex.stop, daemon=True)
    stopping.start()
    stopping.join(30)
    assert not stopping.is_alive()


def test_a_real_time_executor_steps_while_idle() -> None:
    with pytest.raises(ValueError, match="idle_steps"):
        Executor(realtime=True, idle_steps=False)
