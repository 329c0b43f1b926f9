"""Whether a process of a fleet still runs, and stopping processes by PID: the one place roco
reads ``/proc/<pid>/stat`` (proc(5)).

Used by ``roco down`` (the fleet of ``roco up``), ``roco fault`` (services/fault/process.py) and
the two hosts of ``roco hosts`` (services/hosts/netns.py).
"""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path

ENDED = ("Z", "X")
"""The states of ``/proc/<pid>/stat`` of a process that ended: zombie (not yet reaped), dead."""


def proc_state(pid: int) -> str | None:
    """The state letter of ``/proc/<pid>/stat`` (R running, S sleeping, T stopped, Z zombie…);
    None when the process is gone. The state is the first field after the command name in
    parentheses, which may itself hold spaces and ``)``: the text is split after the last ``)``
    (proc(5), ``/proc/pid/stat`` fields 2 and 3)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    _, paren, rest = stat.rpartition(")")
    fields = rest.split()
    return fields[0] if paren and fields else None


def running(pid: int) -> bool:
    """Whether process ``pid`` still runs; a zombie (ended, not yet reaped) does not. A process
    of another user that runs counts (signal 0 is refused, its ``stat`` is readable)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    return proc_state(pid) not in (None, *ENDED)


def stop_pids(
    pids: dict[str, int], grace_s: float = 10.0, *, on_end: Callable[[str, bool], None] | None = None
) -> None:
    """SIGTERM every process of ``pids`` (service name → PID) at once and wait until each has
    ended; SIGKILL what is left after ``grace_s`` seconds. ``on_end(name, killed)`` is called as
    each one ends (``killed``: it had to be SIGKILLed). A process already gone is fine."""
    for pid in pids.values():
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
    left = dict(pids)
    deadline = time.monotonic() + grace_s
    while left:
        for name in [n for n, pid in left.items() if not running(pid)]:
            del left[name]
            if on_end is not None:
                on_end(name, False)
        if left and time.monotonic() > deadline:
            for name, pid in left.items():
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                if on_end is not None:
                    on_end(name, True)
            return
        time.sleep(0.05)
