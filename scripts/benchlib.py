"""What every benchmark prints first: the machine and the library versions its figures were
measured on (README: every number says how it was measured and on what)."""

from __future__ import annotations

import os
import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path


def cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo, else what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def machine(packages: tuple[str, ...] = ()) -> str:
    """One line: CPU model, usable cores, OS, Python and the versions of ``packages``
    (distribution names, e.g. ``"mujoco"``; "not installed" for a missing one)."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    libs = []
    for p in packages:
        try:
            libs.append(f"{p} {version(p)}")
        except PackageNotFoundError:
            libs.append(f"{p} not installed")
    tail = f"; {', '.join(libs)}" if libs else ""
    return (
        f"{cpu_model()}, {usable} of {os.cpu_count()} cores, {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}{tail}"
    )
