"""The deadline monitor of the control loop (velma/executor/timing.py) and the real-time setup
(velma/realtime.py)."""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from velma import realtime
from velma.executor.timing import PARTS, STALL_OFF_CPU, DeadlineMonitor
from velma.realtime import RealtimeSetup, enter_realtime, hold_cpu_latency

DT = 0.001


def test_overruns_lateness_and_runs() -> None:
    m = DeadlineMonitor(DT, realtime=True, window=8)
    # (release, start, end) in s
    assert not m.record(0.000, 0.0000, 0.0005)  # on time
    assert m.record(0.001, 0.0012, 0.0021)  # started late, ended after the next release
    assert m.record(0.002, 0.0025, 0.0031)
    assert not m.record(0.003, 0.0031, 0.0035)
    assert m.record(0.004, 0.0040, 0.0052)
    s = m.stats(sim_time=0.005)
    assert s.cycles == 5 and s.overruns == 3
    assert s.max_consecutive_overruns == 2
    assert s.overrun_share == pytest.approx(0.6)
    assert s.compute_max_us == pytest.approx(1200.0)
    assert s.lateness_max_us == pytest.approx(500.0)
    assert s.lateness_p50_us == pytest.approx(100.0)
    assert s.pacing == "realtime"


def test_window_wraps_and_totals_stay() -> None:
    m = DeadlineMonitor(DT, realtime=False, window=4)
    for k in range(10):
        t = k * 0.01
        m.record(t, t, t + (0.002 if k < 6 else 0.0001))  # the first six overran
    s = m.stats()
    assert s.cycles == 10 and s.overruns == 6 and s.window == 4
    assert s.compute_max_us == pytest.approx(100.0)  # the window holds only the last four


def test_shared_buffer_is_read_by_another_monitor() -> None:
    buf = memoryview(bytearray(DeadlineMonitor.nbytes(16)))
    writer = DeadlineMonitor(DT, realtime=True, window=16, buffer=buf)
    reader = DeadlineMonitor(DT, realtime=True, window=16, buffer=buf)
    writer.record(0.0, 0.0, 0.0004)
    writer.record(0.001, 0.001, 0.0025)
    s = reader.stats()
    assert s.cycles == 2 and s.overruns == 1 and s.compute_max_us == pytest.approx(1500.0)
    with pytest.raises(ValueError, match="smaller"):
        DeadlineMonitor(DT, realtime=True, window=17, buffer=buf)


def _setup_in_child(out: multiprocessing.queues.Queue[tuple[RealtimeSetup, int, set[int]]]) -> None:
    setup = enter_realtime(priority=10)
    out.put((setup, os.sched_getscheduler(0), os.sched_getaffinity(0)))


def test_enter_realtime_reports_what_it_got() -> None:
    """Run in a spawned child (never change the test process's scheduling): whatever the OS
    granted, the report matches the process's actual policy and CPU set."""
    ctx = multiprocessing.get_context("spawn")
    q: multiprocessing.queues.Queue[tuple[RealtimeSetup, int, set[int]]] = ctx.Queue()
    p = ctx.Process(target=_setup_in_child, args=(q,))
    p.start()
    setup, policy, cpus = q.get(timeout=30)
    p.join(10)
    assert (setup.policy == "SCHED_FIFO") == (policy == os.SCHED_FIFO)
    assert set(setup.cpus) == cpus
    assert setup.pinned == (len(cpus) == 1 and len(os.sched_getaffinity(0)) > 1)
    if setup.policy != "SCHED_FIFO":
        assert any("SCHED_FIFO" in n for n in setup.notes)
    assert setup.cpu_latency_us == 0 or any(n.startswith("PM QoS") for n in setup.notes)


def test_worst_cycle_is_remembered_beyond_the_window() -> None:
    m = DeadlineMonitor(DT, realtime=False, window=2)
    for k, compute in enumerate([0.0003, 0.004, 0.0002, 0.0001, 0.0002]):
        m.record(k * 0.01, k * 0.01, k * 0.01 + compute)
    s = m.stats()
    assert s.worst_cycle == 1 and s.worst_compute_us == pytest.approx(4000.0)
    assert s.compute_max_us == pytest.approx(200.0)


def test_the_compute_time_is_split_in_parts_and_a_reader_sees_them() -> None:
    buf = memoryview(bytearray(DeadlineMonitor.nbytes(8)))
    writer = DeadlineMonitor(DT, realtime=True, window=8, buffer=buf)
    # compute 500 µs: primitive 50, control 100, physics 300 → hand-offs 50
    for k in range(4):
        t = k * DT
        writer.record(t, t, t + 0.0005, np.array([0.00005, 0.0001, 0.0003]))
    s = DeadlineMonitor(DT, realtime=True, window=8, buffer=buf).stats()
    assert [p.name for p in s.parts] == list(PARTS)
    split = {p.name: p for p in s.parts}
    for name, us in (("primitive", 50.0), ("control", 100.0), ("physics", 300.0), ("hand-offs", 50.0)):
        assert split[name].p50_us == pytest.approx(us, abs=1e-6)
        assert split[name].max_us == pytest.approx(us, abs=1e-6)


def test_stalls_are_cycles_the_machine_took_the_cpu_from() -> None:
    """A cycle whose compute time exceeds its thread CPU time by more than STALL_OFF_CPU is a
    stall; the longest cycle outside the stalls is reported beside the longest of all, and a
    reader of the shared buffer sees the same."""
    buf = memoryview(bytearray(DeadlineMonitor.nbytes(8)))
    writer = DeadlineMonitor(DT, realtime=True, window=8, buffer=buf)
    cycles = [  # (compute, CPU time) s
        (0.0003, 0.0003),
        (0.0009, 0.00088),  # long, but the thread worked all along: not a stall
        (0.0050, 0.0003),  # 4.7 ms off the CPU: a stall
        (0.0004, 0.0004 - 0.9 * STALL_OFF_CPU),  # off the CPU, but less than the threshold
    ]
    for k, (compute, cpu) in enumerate(cycles):
        writer.record(k * DT, k * DT, k * DT + compute, None, cpu)
    s = DeadlineMonitor(DT, realtime=True, window=8, buffer=buf).stats()
    assert s.stalls == 1
    assert s.long_cycles == 1  # the 5 ms one; the 0.9 ms one stayed within the period
    assert s.compute_max_us == pytest.approx(5000.0)
    assert s.compute_max_outside_stalls_us == pytest.approx(900.0)
    assert s.off_cpu_max_us == pytest.approx(4700.0)
    unmeasured = DeadlineMonitor(DT, realtime=False, window=4)
    unmeasured.record(0.0, 0.0, 0.005)
    assert unmeasured.stats().stalls == 0 and unmeasured.stats().off_cpu_max_us == 0.0


def test_the_cpu_latency_request_is_held_or_refused_with_a_reason(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """``hold_cpu_latency`` writes the 32-bit latency to the PM QoS file and keeps it open;
    without one it says why in one line; the setup's phrase names what was granted."""
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    monkeypatch.setattr(realtime, "PM_QOS_DEVICE", str(device))
    monkeypatch.setattr(realtime, "_held_qos", [])
    assert hold_cpu_latency(0) is None
    assert device.read_bytes() == (0).to_bytes(4, sys.byteorder)
    assert len(realtime._held_qos) == 1  # held open: the request lasts while the file is open
    os.close(realtime._held_qos.pop())
    monkeypatch.setattr(realtime, "PM_QOS_DEVICE", str(tmp_path / "missing"))
    reason = hold_cpu_latency(0)
    assert reason is not None and reason.startswith("PM QoS refused:") and "\n" not in reason
    granted = RealtimeSetup(policy="SCHED_FIFO", priority=80, cpus=(1,), pinned=True, cpu_latency_us=0)
    assert granted.describe() == "SCHED_FIFO pinned, PM QoS 0 µs"
    assert (
        RealtimeSetup(policy="SCHED_OTHER", priority=0, cpus=(0, 1), pinned=False).describe() == "SCHED_OTHER"
    )


def test_a_loop_that_does_not_measure_parts_reports_none() -> None:
    m = DeadlineMonitor(DT, realtime=False, window=4)
    m.record(0.0, 0.0, 0.0004)
    assert m.stats().parts == ()


def test_the_threaded_executor_measures_control_and_physics_in_every_cycle() -> None:
    from velma.executor import Executor

    ex = Executor(seed=0)
    ex.start()
    deadline = time.monotonic() + 60.0
    try:
        while ex.timing().cycles < 200:  # the loop runs as fast as it can
            assert time.monotonic() < deadline, "the loop did not run 200 cycles in 60 s"
    finally:
        ex.stop()
    split = {p.name: p for p in ex.timing().parts}
    assert split["control"].p50_us > 0 and split["physics"].p50_us > 0
    assert split["physics"].p50_us > split["control"].p50_us / 10  # mj_step is no rounding error


def _world_setup_in_child(out: multiprocessing.queues.Queue[tuple[str, int, int, set[int]]]) -> None:
    from velma.world.main import _realtime_setup

    line = _realtime_setup()
    out.put((line, os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, os.sched_getaffinity(0)))


def test_the_world_takes_the_first_cpu_below_the_loop() -> None:
    """The world process's real-time setup (velma/world/main.py), in a spawned child: granted,
    it runs SCHED_FIFO just below the loop's priority on the lowest-numbered CPU (the loop
    takes the highest); refused, its line says why."""
    ctx = multiprocessing.get_context("spawn")
    q: multiprocessing.queues.Queue[tuple[str, int, int, set[int]]] = ctx.Queue()
    p = ctx.Process(target=_world_setup_in_child, args=(q,))
    p.start()
    line, policy, priority, cpus = q.get(timeout=30)
    p.join(10)
    allowed = sorted(os.sched_getaffinity(0))
    if policy != os.SCHED_FIFO:
        assert "SCHED_FIFO refused" in line, line
        return
    assert line.startswith("SCHED_FIFO")
    assert priority == realtime.WORLD_FIFO_PRIORITY < realtime.FIFO_PRIORITY
    if len(allowed) > 1:
        assert cpus == {allowed[0]} and "pinned" in line
