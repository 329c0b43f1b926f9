"""The process-alive check of services/fleet/processes.py reads the state of a process whose
command name holds a space and ``)`` (``/proc/PID/stat``: ``PID (a b) c) S …``), running and
after it ended (a zombie until reaped)."""

from __future__ import annotations

import os
import subprocess
import sys

from services.fleet.processes import proc_state, running

NAME = "a b) c"
"""A command name (at most 15 bytes: /proc/PID/comm) that a split on spaces misreads."""

CHILD = f"""
import sys
with open("/proc/self/comm", "w") as comm:
    comm.write({NAME!r})
print("ready", flush=True)
sys.stdin.read()
"""


def test_a_name_with_a_space_and_a_paren_is_read_running_then_ended() -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None and child.stdout.readline() == "ready\n"
        with open(f"/proc/{child.pid}/comm") as comm:
            assert comm.read().strip() == NAME
        assert proc_state(child.pid) in ("R", "S")
        assert running(child.pid)
        assert child.stdin is not None
        child.stdin.close()
        # ended but not reaped: WNOWAIT leaves it a zombie
        os.waitid(os.P_PID, child.pid, os.WEXITED | os.WNOWAIT)
        assert proc_state(child.pid) == "Z"
        assert not running(child.pid)
    finally:
        child.kill()
        child.wait()
    assert proc_state(child.pid) is None
    assert not running(child.pid)
