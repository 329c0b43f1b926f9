"""``roco chaos --load N`` (services/scenario/load.py): N processes keep a core busy each beside
the fleet while the run lasts, are ended with it, and the report says how much CPU they took."""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Connection
from pathlib import Path

import pytest

from services.scenario.load import MAX_LOAD, BusyLoad, cpu_seconds

BUSY_S = 0.3
"""CPU time (s) each busy process must reach for the test to count it as busy."""
WITHIN_S = 30.0


def sleep_forever(parent: int) -> None:
    """A planted load that does nothing: it waits instead of computing."""
    threading.Event().wait()


def hold_a_load(conn: Connection) -> None:
    """Body of a process that runs one busy process and waits (to be killed outright)."""
    with BusyLoad(1) as load:
        conn.send(load.pids)
        threading.Event().wait()


def cpu_reached(load: BusyLoad, each_s: float, within_s: float) -> bool:
    """Whether every process of ``load`` used ``each_s`` of CPU within ``within_s`` (polled)."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if load.pids and all(cpu_seconds(pid) >= each_s for pid in load.pids):
            return True
        time.sleep(0.05)
    return False


def test_the_busy_processes_compute_while_the_block_runs_and_end_with_it() -> None:
    with BusyLoad(2) as load:
        pids = load.pids
        assert len(pids) == 2
        assert cpu_reached(load, BUSY_S, WITHIN_S)
    assert load.cpu_s >= 2 * BUSY_S
    assert all(not Path(f"/proc/{pid}").exists() for pid in pids)
    line = load.line(10.0)
    assert line.startswith("load: 2 busy process(es) beside the fleet, ") and "s of CPU over 10.0 s" in line


def test_a_load_that_does_not_compute_is_seen_not_to() -> None:
    """The check of the test above catches a planted load that only waits."""
    with BusyLoad(1, target=sleep_forever) as load:
        assert load.pids
        assert not cpu_reached(load, BUSY_S, 1.0)
    assert load.cpu_s < BUSY_S


def test_no_load_starts_nothing_and_says_so() -> None:
    with BusyLoad(0) as load:
        assert load.pids == []
    assert load.line(5.0) == "load: none (the machine as it was)"


def test_a_busy_process_ends_itself_when_its_parent_was_killed() -> None:
    ctx = mp.get_context("spawn")
    ours, theirs = ctx.Pipe()
    holder = ctx.Process(target=hold_a_load, args=(theirs,))
    holder.start()
    assert ours.poll(WITHIN_S)
    (spinner,) = ours.recv()
    try:
        holder.kill()  # SIGKILL: no __exit__ runs in the holder
        holder.join()
        deadline = time.monotonic() + 10.0
        while Path(f"/proc/{spinner}").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not Path(f"/proc/{spinner}").exists()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(spinner, signal.SIGKILL)


@pytest.mark.parametrize("n", [-1, MAX_LOAD + 1])
def test_a_load_out_of_range_is_refused(n: int) -> None:
    with pytest.raises(ValueError, match=f"0 to {MAX_LOAD} busy processes, not {n}"):
        BusyLoad(n)


def test_roco_chaos_refuses_a_load_out_of_range_with_one_line() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "services.cli", "chaos", "--load", str(MAX_LOAD + 1)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 2
    assert (
        out.stderr.strip() == f"roco: --load: the load is 0 to {MAX_LOAD} busy processes, not {MAX_LOAD + 1}"
    )
