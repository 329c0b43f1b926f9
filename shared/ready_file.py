"""A process's readiness as a file: written once the process is ready, removed when it stops.

A container's health check tests the file with a program as small as ``cat`` instead of asking
the process itself (deploy/compose.yaml: ``ROCO_READY_FILE``), so a check costs no interpreter,
no connection and nothing in the process. What the file holds is one line saying what is ready
(``cat`` shows it in ``docker inspect``'s health log). Who writes it and when:
services/runtime/main.py (an agent: its roles set up and the agents it asks seen),
services/recorder/recorder.py, services/runtime/router.py and velma/world/main.py.

The file is written whole (a temporary file renamed over it), so a reader sees it absent or
complete. Imports nothing of roco.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

__all__ = ["clear", "mark"]


def mark(path: Path | None, what: str) -> str | None:
    """Write ``what`` (one line, e.g. ``"a_km ready: ..."``) to ``path``, whole; nothing when
    ``path`` is None. Returns None when written (or nothing to write), else why not (one line:
    a process goes on without it, and its health check says unhealthy)."""
    if path is None:
        return None
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(what.replace("\n", " ") + "\n")
        tmp.replace(path)
    except OSError as exc:
        return f"cannot write the ready file {path}: {exc.strerror or exc}"
    return None


def clear(path: Path | None) -> None:
    """Remove ``path`` (not ready: at a process's start, so that a file left by a killed one does
    not speak for it, and at its stop); nothing when it is None or absent."""
    if path is None:
        return
    with contextlib.suppress(FileNotFoundError):
        path.unlink()
