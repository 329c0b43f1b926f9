"""How busy the machine is around a benchmark: waiting for a quiet machine before a timed part,
and the CPU share others (and the hypervisor) took while it ran.

Figures from `roco bench` on a shared 2-core VM move with what else runs: another job's
processes, the previous part's processes still ending, and the hypervisor's steal (the time
the VM's virtual CPUs were ready but not run). The load average shows these late (it decays
over a minute, and counts sleeping-in-I/O threads); ``/proc/stat``'s CPU times show them
at once. Source: proc(5), ``/proc/stat`` (the first ``cpu`` line: user, nice, system, idle,
iowait, irq, softirq, steal, …, in clock ticks summed over the CPUs).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

STAT = Path("/proc/stat")
QUIET_BUSY = 0.10
"""A machine is quiet when at most this share of its CPU time was busy or stolen over a window."""
WINDOW_S = 1.0
"""How long one look at the machine lasts (s)."""
DEFAULT_WAIT_S = 90.0
"""How long :func:`settle` waits at most for a quiet machine (s) before it goes on anyway."""


def quiet_rule() -> str:
    """What :func:`settle` calls a quiet machine, in words (for help texts and reports)."""
    return f"≤ {QUIET_BUSY * 100:.0f} % of its CPU time busy or stolen over {WINDOW_S:.0f} s"


@dataclass(frozen=True)
class CpuTimes:
    """The machine's CPU times (clock ticks over all CPUs) from ``/proc/stat``."""

    busy: int
    """user + nice + system + irq + softirq ticks."""
    idle: int
    """idle + iowait ticks."""
    steal: int
    """Ticks the hypervisor ran something else while a virtual CPU was ready."""

    @property
    def total(self) -> int:
        """All ticks: busy, idle and stolen."""
        return self.busy + self.idle + self.steal


def read(stat: Path = STAT) -> CpuTimes | None:
    """The machine's CPU times now; None where ``/proc/stat`` cannot be read (not Linux)."""
    try:
        fields = stat.read_text().split("\n", 1)[0].split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu":
        return None
    v = [int(x) for x in fields[1:9]] + [0] * max(0, 9 - len(fields))
    user, nice, system, idle, iowait, irq, softirq, steal = v[:8]
    return CpuTimes(user + nice + system + irq + softirq, idle + iowait, steal)


@dataclass(frozen=True)
class Share:
    """What share (0–1) of the machine's CPU time between two readings was busy and stolen."""

    busy: float
    steal: float

    @property
    def taken(self) -> float:
        """Busy or stolen: not available to whoever was waiting for a CPU."""
        return self.busy + self.steal

    def text(self) -> str:
        """The two shares in per cent, e.g. ``4 % busy, 0 % stolen``."""
        return f"{self.busy * 100:.0f} % busy, {self.steal * 100:.0f} % stolen"


def share(before: CpuTimes | None, after: CpuTimes | None) -> Share | None:
    """The busy and stolen shares between two readings; None without both or with no time."""
    if before is None or after is None:
        return None
    total = after.total - before.total
    if total <= 0:
        return None
    return Share((after.busy - before.busy) / total, (after.steal - before.steal) / total)


@dataclass(frozen=True)
class Settled:
    """What :func:`settle` found: how long it waited (s), the last window's shares, and whether
    that window was quiet."""

    waited_s: float
    last: Share | None
    quiet: bool

    def text(self) -> str:
        """One line for the report: the wait (s), whether it ended quiet, the last window."""
        if self.last is None:
            return "the machine's CPU times could not be read"
        state = "quiet" if self.quiet else "still not quiet"
        return f"waited {self.waited_s:.0f} s; {state} ({self.last.text()} over the last {WINDOW_S:.0f} s)"


def settle(
    max_wait_s: float = DEFAULT_WAIT_S,
    *,
    quiet_busy: float = QUIET_BUSY,
    window_s: float = WINDOW_S,
    reader: Callable[[], CpuTimes | None] = read,
    sleep: Callable[[float], None] = time.sleep,
) -> Settled:
    """Wait, looking at the machine ``window_s`` at a time, until one window's busy and stolen
    share is at most ``quiet_busy`` or ``max_wait_s`` has passed (the caller then goes on: the
    result says so). The caller must itself be idle meanwhile (it is counted too)."""
    waited = 0.0
    last: Share | None = None
    while True:
        before = reader()
        sleep(window_s)
        waited += window_s
        last = share(before, reader())
        if last is None:
            return Settled(waited, None, False)
        if last.taken <= quiet_busy:
            return Settled(waited, last, True)
        if waited >= max_wait_s:
            return Settled(waited, last, False)
