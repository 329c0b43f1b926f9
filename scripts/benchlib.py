"""What every benchmark prints first: the machine and the library versions its figures were
measured on (README: every number says how it was measured and on what)."""

from __future__ import annotations

import os
import platform
from importlib.metadata import PackageNotFoundError, version

from services.bench import report

cpu_model = report.cpu_model
"""The CPU model name (services/bench/report.py: one copy for roco bench and these scripts)."""


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
