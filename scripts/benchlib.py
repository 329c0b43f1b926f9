"""What every benchmark prints first: the machine and the library versions its figures were
measured on (README: every number says how it was measured and on what)."""

from __future__ import annotations

import os
import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import NamedTuple

from services.bench import report, run_header

cpu_model = report.cpu_model
"""The CPU model name (services/bench/report.py: one copy for roco bench and these scripts)."""


def versions(packages: tuple[str, ...]) -> list[str]:
    """``"NAME VERSION"`` of each of ``packages`` (distribution names, e.g. ``"mujoco"``;
    ``"NAME not installed"`` for a missing one)."""
    libs = []
    for p in packages:
        try:
            libs.append(f"{p} {version(p)}")
        except PackageNotFoundError:
            libs.append(f"{p} not installed")
    return libs


def header(packages: tuple[str, ...] = ()) -> str:
    """The header a script's Markdown output opens with (services/bench/run_header.py: its
    command line, commit, date and machine, read back by the README's figures), and the
    versions of ``packages``: lines ending in a newline."""
    lines = run_header.script_lines()
    if packages:
        lines.append(f"- Versions: {', '.join(versions(packages))}.")
    return "\n".join(lines) + "\n"


def machine(packages: tuple[str, ...] = ()) -> str:
    """One line: CPU model, usable cores, OS, Python and the versions of ``packages``
    (distribution names, e.g. ``"mujoco"``; "not installed" for a missing one)."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    libs = versions(packages)
    tail = f"; {', '.join(libs)}" if libs else ""
    return (
        f"{cpu_model()}, {usable} of {os.cpu_count()} cores, {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}{tail}"
    )


class ThreadUse(NamedTuple):
    """What one thread has used so far: its name (``comm``), CPU time in clock ticks
    (``os.sysconf("SC_CLK_TCK")`` a second) in user and system mode, and its voluntary (it
    slept: a queue, a socket, a lock) and involuntary (its core was taken) context switches."""

    name: str
    user: int
    system: int
    voluntary: int
    involuntary: int


def thread_use(pid: int) -> dict[int, ThreadUse]:
    """Every thread of process ``pid`` (thread id → :class:`ThreadUse`), from
    ``/proc/<pid>/task/<tid>/stat`` and ``status`` (Linux); a thread that ends while it is read
    is left out. Raises OSError when the process is gone."""
    out: dict[int, ThreadUse] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            name = (task / "comm").read_text().strip()
            stat = (task / "stat").read_text().rsplit(")", 1)[1].split()
            status = dict(
                line.split(":", 1) for line in (task / "status").read_text().splitlines() if ":" in line
            )
        except OSError:  # the thread ended meanwhile
            continue
        out[int(task.name)] = ThreadUse(
            name,
            int(stat[11]),
            int(stat[12]),
            int(status["voluntary_ctxt_switches"]),
            int(status["nonvoluntary_ctxt_switches"]),
        )
    return out
