"""The processes a benchmark part starts (a SPADE server, JADE's JVMs): ended and reaped."""

from __future__ import annotations

import signal
import subprocess
from typing import Any

GRACE_S = 5.0
"""How long a child has to end after SIGTERM before SIGKILL (s)."""


def end_child(proc: subprocess.Popen[Any]) -> None:
    """End ``proc`` (SIGTERM, then SIGKILL after :data:`GRACE_S`) and reap it."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(GRACE_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(GRACE_S)
