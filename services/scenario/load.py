"""A busy machine on purpose: processes that each keep one core busy beside a fleet, so that a
scenario or a chaos run (``roco chaos --load N``) shows how the robot does when the machine is
shared. Each process spins in Python without sleeping (a CPU-bound neighbour, as a build or a
second simulation would be); they are started with spawn, ended by their process ids when the
block ends (and end themselves once their parent is gone: a run killed outright leaves no
spinner behind), and their CPU time is read from ``/proc/<pid>/stat`` (proc(5), fields 14 and 15)
so that a report can say how much work they took from the fleet.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing.process import BaseProcess
from pathlib import Path
from types import TracebackType

MAX_LOAD = 64
"""Busy processes a run may ask for (``--load``): enough to saturate any machine roco runs on."""
STOP_TIMEOUT_S = 5.0
"""How long a busy process is given to end after SIGTERM before it is killed."""


ORPHAN_CHECK_EVERY = 1 << 20
"""Iterations of :func:`spin` between two looks at its parent (≈ 50 ms of one core)."""


def spin(parent: int) -> None:
    """Body of one busy process: compute until ended by a signal or until process ``parent``
    is no longer its parent (it ended; the process was handed to init)."""
    while os.getppid() == parent:
        n = 0
        while n < ORPHAN_CHECK_EVERY:
            n += 1


def cpu_seconds(pid: int) -> float:
    """CPU time (s, user + system) process ``pid`` has used, from ``/proc/<pid>/stat``. Raises
    OSError when the process is gone."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@dataclass
class BusyLoad:
    """``n`` busy processes (0 ≤ n ≤ :data:`MAX_LOAD`) while the ``with`` block runs, each
    running ``target(parent pid)`` (:func:`spin`; a module-level function, as spawn imports it
    again); raises
    ValueError for another ``n``. :attr:`cpu_s` holds the CPU time they used (s, all of them)
    once the block has ended."""

    n: int
    target: Callable[[int], None] = spin
    cpu_s: float = 0.0
    _procs: list[BaseProcess] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not 0 <= self.n <= MAX_LOAD:
            raise ValueError(f"the load is 0 to {MAX_LOAD} busy processes, not {self.n}")

    def __enter__(self) -> BusyLoad:
        ctx = mp.get_context("spawn")
        for k in range(self.n):
            p = ctx.Process(target=self.target, args=(os.getpid(),), name=f"roco-load-{k}", daemon=True)
            p.start()
            self._procs.append(p)
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.cpu_s = self.used()
        for p in self._procs:
            p.terminate()
        for p in self._procs:
            p.join(STOP_TIMEOUT_S)
            if p.is_alive():
                p.kill()
                p.join()
        self._procs.clear()

    @property
    def pids(self) -> list[int]:
        """The process ids of the busy processes running now."""
        return [p.pid for p in self._procs if p.pid is not None]

    def used(self) -> float:
        """CPU time (s) the busy processes running now have used, all of them."""
        total = 0.0
        for pid in self.pids:
            try:
                total += cpu_seconds(pid)
            except OSError:  # ended already (killed from outside): its time is not known
                continue
        return total

    def line(self, wall_s: float) -> str:
        """One line for a report: how many processes, and the cores' worth they kept busy over
        ``wall_s`` seconds of the run (their CPU time over it)."""
        if self.n == 0:
            return "load: none (the machine as it was)"
        cores = self.cpu_s / wall_s if wall_s > 0 else 0.0
        return (
            f"load: {self.n} busy process(es) beside the fleet, {self.cpu_s:.1f} s of CPU over "
            f"{wall_s:.1f} s ({cores:.2f} cores)"
        )
