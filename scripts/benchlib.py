"""What every benchmark prints first: the machine and the library versions its figures were
measured on (README: every number says how it was measured and on what)."""

from __future__ import annotations

import contextlib
import io
import os
import platform
import sys
from collections.abc import Iterator
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import NamedTuple, TextIO

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


EARLIER = "## Earlier runs"
"""The heading under which a document keeps the runs before its current one (docs/bench/loop.md)."""


class _Tee(io.TextIOBase):
    """Text written to the terminal and kept."""

    def __init__(self, terminal: TextIO) -> None:
        self.terminal, self.kept = terminal, io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.terminal.write(text)

    def flush(self) -> None:
        self.terminal.flush()


@contextlib.contextmanager
def recorded(out: Path | None) -> Iterator[None]:
    """Print as usual; with ``out``, also write what was printed to ``out`` as its current run,
    once the block ends without an exception: the file's text from its first :data:`EARLIER`
    heading on is kept below it (a document's earlier runs); the rest is replaced. Nothing is
    written when the block raises (a run that did not finish is not a measurement)."""
    if out is None:
        yield
        return
    tee = _Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        yield
    old = out.read_text() if out.exists() else ""
    earlier = old[old.index(EARLIER) :] if EARLIER in old else ""
    text = tee.kept.getvalue().rstrip("\n") + "\n"
    out.write_text(text + ("\n" + earlier if earlier else ""))


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
