"""A child process's standard output as a queue of lines, read on a thread of its own (for
tests that wait for a line while the process runs)."""

from __future__ import annotations

import queue
import subprocess
import threading


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
