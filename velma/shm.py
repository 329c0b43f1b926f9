"""Named blocks of POSIX shared memory (``multiprocessing.shared_memory``) for the robot's
processes: the world's link to its controller (velma/world/link.py) and ag_ex's hand-offs
(velma/executor/handoff.py).

Every block is named ``roco_<creator's pid>_<random>`` (:func:`new_block`): a creator killed
with SIGKILL (``roco fault``, a chaos scenario, an OOM kill) cannot unlink its blocks, and
Python's resource tracker, killed with it, does not either; the next creator removes the blocks
of creators that are gone (:func:`remove_orphans`) instead of leaving them in ``/dev/shm``
(RAM) for good.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from multiprocessing import shared_memory
from pathlib import Path


class BlockError(ValueError):
    """A shared block that is closed, or has the wrong size or contents."""


BLOCK_PREFIX = "roco_"
"""Start of the name of every block made here: ``roco_<pid>_<8 hex digits>``."""
SHM_DIR = Path("/dev/shm")
"""Where Linux keeps POSIX shared memory (tmpfs: a block occupies RAM until unlinked)."""


def new_block(size: int) -> shared_memory.SharedMemory:
    """A new block of ``size`` bytes named after this process (``roco_<pid>_<random>``).
    Raises OSError when the system refuses it (e.g. /dev/shm full)."""
    name = f"{BLOCK_PREFIX}{os.getpid()}_{secrets.token_hex(4)}"
    return shared_memory.SharedMemory(name=name, create=True, size=size)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


def remove_orphans(shm_dir: Path = SHM_DIR) -> list[str]:
    """Unlink the blocks of :func:`new_block` whose creator process no longer exists; returns
    their names. Blocks of live processes, and every other file, are left alone (a PID that was
    reused keeps its blocks: they are only left over, never taken). Nothing when ``shm_dir``
    does not exist (not Linux); a block that another process removes meanwhile is skipped."""
    gone: list[str] = []
    try:
        entries = list(shm_dir.iterdir())
    except OSError:
        return gone
    for entry in entries:
        pid_text, _, rest = entry.name.removeprefix(BLOCK_PREFIX).partition("_")
        if not entry.name.startswith(BLOCK_PREFIX) or not pid_text.isdigit() or not rest:
            continue
        if _alive(int(pid_text)):
            continue
        with contextlib.suppress(FileNotFoundError, PermissionError):
            entry.unlink()
            gone.append(entry.name)
    return gone


def shared_view(shm: shared_memory.SharedMemory) -> memoryview:
    """The block's buffer (typeshed marks it optional: it is None only after ``close``)."""
    buf = shm.buf
    if buf is None:
        raise BlockError(f"shared block {shm.name} is closed")
    return buf
