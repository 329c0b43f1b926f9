"""A fleet's processes seen from outside: whether one runs, which belong to a run folder, and
what roco said (its ``roco:`` lines)."""

from __future__ import annotations

import os
from pathlib import Path


def said(stream: str) -> list[str]:
    """The lines roco said (a stale compiled module's warning of a development checkout aside)."""
    return [line for line in stream.splitlines() if line.startswith("roco")]


def running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def processes_of(run_dir: Path) -> list[int]:
    """Every process whose environment names ``run_dir`` as its run folder (a fleet's processes
    and their children: ag_ex's loop and camera processes)."""
    mark = f"ROCO_RUN_DIR={run_dir}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            env = (entry / "environ").read_bytes().split(b"\0")
        except OSError:
            continue
        if mark in env and running(int(entry.name)):
            found.append(int(entry.name))
    return found
