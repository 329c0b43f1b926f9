"""A child process's standard output as a queue of lines, read on a thread of its own (for
tests that wait for a line while the process runs), and waiting for what a process writes to a
file (its log) against a deadline."""

from __future__ import annotations

import queue
import subprocess
import threading
import time
from collections.abc import Callable

import pytest


def lines_of(proc: subprocess.Popen[str]) -> queue.SimpleQueue[str | None]:
    """A queue of ``proc``'s stdout lines (without their newline), None at its end."""
    out: queue.SimpleQueue[str | None] = queue.SimpleQueue()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            out.put(line.rstrip("\n"))
        out.put(None)

    threading.Thread(target=read, daemon=True).start()
    return out


def wait_until(condition: Callable[[], bool], timeout: float, what: str) -> None:
    """Return once ``condition()`` holds (asked every 50 ms: e.g. a line in another process's
    log); fail the test, naming ``what``, after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"not within {timeout:.0f} s: {what}")
        time.sleep(0.05)
