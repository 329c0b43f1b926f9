"""The header a benchmark's Markdown output opens with, saying which run its figures are from,
and its reader.

Two lines, the format of docs/benchmarks.md's "This run" (services/bench/report.py
``machine_lines``), written by the scripts too (scripts/bench_loop.py,
scripts/bench_pour_seeds.py)::

    - Command: `python scripts/bench_loop.py --repeat 3`, at commit 511ff40, 2026-11-25 19:10 UTC.
    - CPU: Intel(R) Xeon(R) Processor, 2 of 2 cores usable; memory 23.5 GiB; Linux 6.18.

``roco bench`` puts ``(took N s)`` after the command. :func:`read` takes the first header of a
document: a file that keeps earlier runs below its current one is read at its current run.
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import shlex
import sys
from dataclasses import dataclass

from services.bench import report

COMMAND_RE = re.compile(
    r"^- Command: `(?P<command>[^`]+)`(?: \(took \d+ s\))?, at commit "
    r"(?P<commit>[0-9a-f]{7,40}(?: \+ working tree)?), (?P<date>\d{4}-\d{2}-\d{2}[^.]*)\.",
    re.MULTILINE,
)
CPU_RE = re.compile(
    r"^- CPU: (?P<cpu>[^,;\n]+), (?P<usable>\d+) of (?P<cores>\d+) cores usable", re.MULTILINE
)


class HeaderError(ValueError):
    """A document without the header of the run its figures are from."""


@dataclass(frozen=True)
class RunHeader:
    """Which run a document's figures are from, as the run recorded it."""

    command: str
    """The command line, e.g. ``roco bench`` or ``python scripts/bench_loop.py --repeat 3``."""
    commit: str
    """The short commit hash, with `` + working tree`` when files were changed."""
    date: str
    """``YYYY-MM-DD`` with, when recorded, the time and zone."""
    cpu: str
    """The CPU model name (/proc/cpuinfo)."""
    cores: int
    """The cores the run could use."""

    @property
    def machine(self) -> str:
        """The CPU and its usable cores, e.g. ``Intel(R) Xeon(R) Processor, 2 cores``."""
        return f"{self.cpu}, {self.cores} core{'s' if self.cores != 1 else ''}"


def read(text: str, where: str = "the document") -> RunHeader:
    """The first run header in ``text`` (a Markdown document). Raises HeaderError naming
    ``where`` when its command line (with commit and date) or its CPU line is missing."""
    command, cpu = COMMAND_RE.search(text), CPU_RE.search(text)
    if command is None:
        raise HeaderError(f"{where}: no line '- Command: `…`, at commit …, YYYY-MM-DD.'")
    if cpu is None:
        raise HeaderError(f"{where}: no line '- CPU: …, N of M cores usable'")
    return RunHeader(
        command["command"], command["commit"], command["date"], cpu["cpu"].strip(), int(cpu["usable"])
    )


def script_lines(argv: list[str] | None = None) -> list[str]:
    """The header of a script's output: its command line (``python`` and ``argv``, default
    ``sys.argv``), the checkout's commit, the date and time, and the machine."""
    args = sys.argv if argv is None else argv
    command = "python " + " ".join(shlex.quote(a) for a in args)
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    date = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    return [
        f"- Command: `{command}`, at commit {report.commit()}, {date}.",
        f"- CPU: {report.cpu_model()}, {usable} of {os.cpu_count()} cores usable; memory "
        f"{report.mem_total_gib():.1f} GiB; {platform.system()} {platform.release()}; "
        f"Python {platform.python_version()}.",
    ]
