"""Deadline monitor and real-time setup of the 1 kHz control loop (paper §5.3: ag_ex is the
hard-timing part of the system; velma/model/README.md "Control").

Definitions (per cycle k, period ``dt`` = 1 ms):

- *release time* r_k = t_0 + k·dt in real-time pacing (the wall-clock instant cycle k is due
  to start); in as-fast-as-possible pacing, the instant the cycle starts.
- *lateness* = start_k − r_k (s, ≥ 0): how late the loop woke up (scheduler latency, the
  previous cycle's overrun).
- *compute time* = end_k − start_k (s): the work of one cycle (command hand-off, motion
  primitive, control law, physics step, state publication).
- *overrun*: end_k > r_k + dt, i.e. the cycle did not finish before the next one was due.
  In as-fast-as-possible pacing this is compute time > dt.
- *off-CPU time* = compute time − the loop thread's CPU time over the cycle
  (``time.thread_time``): how long something else held the loop's CPU during its work. Linux
  does not count a virtual machine's steal time (the host running something else on the
  vCPU's core) or interrupt handling as the thread's CPU time. A *stall* is a cycle with more
  than :data:`STALL_OFF_CPU` s of it: the machine, not the loop's work, lengthened it.

The compute time is split in parts (the budget in the open), each cycle's measured
by the loop itself into a preallocated array (:data:`PARTS` but the last): *primitive* (the
motion primitive: taking the next command, its step), *control* (the impedance law for both
arms and the torso, the hands and the head), *physics* (``mj_step`` and the hands' contact
scan); *hand-offs* is the rest of the cycle (the rings, the state and world publications, the
monitor itself).

``DeadlineMonitor.record`` is O(1) and writes into preallocated arrays (no allocation of
containers on the loop's path); ``stats`` computes percentiles over the last ``window`` cycles
on the caller's side.

The loop's real-time setup (SCHED_FIFO, a CPU of its own, the CPU wake-up latency) is
velma/realtime.py's ``enter_realtime``.
"""

from __future__ import annotations

import time

import msgspec
import numpy as np

from velma.realtime import RealtimeSetup
from velma.world.timing import WorldTiming

DEFAULT_WINDOW = 120_000  # cycles (2 min at 1 kHz) kept for percentiles
PARTS = ("primitive", "control", "physics", "hand-offs")
"""The parts of a cycle's compute time (module docstring); the loop measures all but the last."""
MEASURED_PARTS = len(PARTS) - 1
STALL_OFF_CPU = 100e-6
"""s of off-CPU time within one cycle that make it a stall (module docstring)."""


class PartTiming(msgspec.Struct, frozen=True, kw_only=True):
    """One part of the cycle's compute time over the window (µs): p50, p99 and max each taken
    over that part alone (the parts' p99s do not add up to the cycle's)."""

    name: str
    p50_us: float
    p99_us: float
    max_us: float


class TimingStats(msgspec.Struct, frozen=True, kw_only=True):
    """Loop timing over the last ``window`` cycles (µs), plus totals since start.

    ``pacing`` is ``realtime`` or ``fast``; ``cycles`` and ``overruns`` count since start;
    ``overrun_share`` = overruns / cycles; ``max_consecutive_overruns`` is the longest run of
    overrunning cycles (Franka stops a robot at 20: velma/model/README.md "Control"); ``setup``
    says whether the loop got SCHED_FIFO and a CPU of its own."""

    pacing: str
    cycles: int
    window: int
    compute_p50_us: float
    compute_p99_us: float
    compute_max_us: float
    lateness_p50_us: float
    lateness_p99_us: float
    lateness_max_us: float
    overruns: int
    overrun_share: float
    max_consecutive_overruns: int
    sim_time: float
    setup: RealtimeSetup | None = None
    worst_cycle: int = 0
    """Index (since start) of the cycle with the longest compute time ever recorded; at 1 kHz
    it is also the simulation time in ms, which tells what the robot was doing."""
    worst_compute_us: float = 0.0
    """That cycle's compute time (µs), over the whole run, not only the window."""
    parts: tuple[PartTiming, ...] = ()
    """The compute time split in :data:`PARTS` (empty when the loop did not measure them)."""
    control_law: str = ""
    """The impedance law the loop ran: ``compiled`` or ``python`` (velma/control/compiled.py;
    empty when the loop did not say)."""
    plant: str = ""
    """Where the cycle's MuJoCo side ran: ``compiled`` or ``python`` (velma/executor/plant.py;
    empty when the loop did not say)."""
    long_cycles: int = 0
    """Cycles in the window whose compute time exceeded the period (1 ms)."""
    stalls: int = 0
    """Stalls in the window: cycles that spent more than ``STALL_OFF_CPU`` off their CPU
    (module docstring); 0 when the loop did not measure its CPU time."""
    compute_max_outside_stalls_us: float = 0.0
    """The longest compute time (µs) of the window's cycles that were not stalls."""
    off_cpu_max_us: float = 0.0
    """The longest off-CPU time (µs) of one cycle in the window."""
    world: WorldTiming | None = None
    """The world process's own timing over its run (velma/world/timing.py), when the loop
    controls a world process (None: the physics ran in the loop, or the world was not read)."""


class DeadlineMonitor:
    """Counts every cycle's compute time, lateness and overruns (see module docstring).

    ``window`` (cycles) bounds the memory used for percentiles: 6 float64 arrays of that
    length (compute time, lateness, the three measured parts, the off-CPU time) plus 6
    counters. ``buffer``
    (at least ``DeadlineMonitor.nbytes(window)`` bytes, e.g. a shared memory block) holds
    them when given, so that another process can read ``stats`` while the loop records; a
    reader may see a window torn by one cycle, the counters are single aligned 8-byte
    stores."""

    @staticmethod
    def nbytes(window: int) -> int:
        """Size (B) of the buffer a monitor of ``window`` cycles needs."""
        return 8 * (6 + (3 + MEASURED_PARTS) * window)

    def __init__(
        self, dt: float, *, realtime: bool, window: int = DEFAULT_WINDOW, buffer: memoryview | None = None
    ) -> None:
        if window <= 0:
            raise ValueError(f"window must be positive, got {window}")
        self.dt = dt
        self.realtime = realtime
        self.window = window
        buf = buffer if buffer is not None else memoryview(bytearray(self.nbytes(window)))
        if len(buf) < self.nbytes(window):
            raise ValueError(f"buffer of {len(buf)} B is smaller than {self.nbytes(window)} B")
        self._counters = np.ndarray((5,), dtype=np.int64, buffer=buf, offset=0)
        self._worst = np.ndarray((1,), dtype=np.float64, buffer=buf, offset=40)
        self._compute = np.ndarray((window,), dtype=np.float64, buffer=buf, offset=48)
        self._lateness = np.ndarray((window,), dtype=np.float64, buffer=buf, offset=48 + 8 * window)
        self._parts = np.ndarray(
            (window, MEASURED_PARTS), dtype=np.float64, buffer=buf, offset=48 + 16 * window
        )
        self._off_cpu = np.ndarray(
            (window,), dtype=np.float64, buffer=buf, offset=48 + (2 + MEASURED_PARTS) * 8 * window
        )
        self._cpu_measured = False
        self._measured = False
        self._cycles = int(self._counters[0])
        self._overruns = int(self._counters[1])
        self._consecutive = int(self._counters[2])
        self._max_consecutive = int(self._counters[3])
        self._worst_compute = float(self._worst[0])
        self.setup: RealtimeSetup | None = None
        self.control_law = ""
        """Which impedance law the loop runs (``TimingStats.control_law``), set by its owner."""
        self.plant = ""
        """Where the cycle's MuJoCo side runs (``TimingStats.plant``), set by its owner."""

    @property
    def cycles(self) -> int:
        """Cycles recorded since start."""
        return int(self._counters[0])

    @property
    def overruns(self) -> int:
        """Overrunning cycles since start."""
        return int(self._counters[1])

    def record(
        self,
        release: float,
        start: float,
        end: float,
        parts: np.ndarray | None = None,
        cpu: float | None = None,
    ) -> bool:
        """Record one cycle (times in s, same clock) and, when given, its ``parts``: the
        seconds of the measured :data:`PARTS` (array of 3), and ``cpu``: the loop thread's
        CPU time over the cycle (s, ``time.thread_time``). Returns True when it overran."""
        i = self._cycles % self.window
        compute = end - start
        self._compute[i] = compute
        if cpu is not None:
            self._off_cpu[i] = compute - cpu if compute > cpu else 0.0
            self._cpu_measured = True
        if parts is not None:
            self._parts[i] = parts
            self._measured = True
        if compute > self._worst_compute:
            self._worst_compute = compute
            self._counters[4] = self._cycles
            self._worst[0] = compute
        self._lateness[i] = start - release if start > release else 0.0
        self._cycles += 1
        self._counters[0] = self._cycles
        over = end > release + self.dt
        if over:
            self._overruns += 1
            self._consecutive += 1
            self._counters[1] = self._overruns
            if self._consecutive > self._max_consecutive:
                self._max_consecutive = self._consecutive
                self._counters[3] = self._max_consecutive
        else:
            self._consecutive = 0
        return over

    def stats(self, sim_time: float = 0.0) -> TimingStats:
        """Percentiles over the window (µs) and the totals (see ``TimingStats``)."""
        cycles, overruns, _, max_consecutive, worst_cycle = (int(x) for x in self._counters)
        n = min(cycles, self.window)
        comp = self._compute[:n] * 1e6
        late = self._lateness[:n] * 1e6

        def pct(a: np.ndarray, q: float) -> float:
            return float(np.percentile(a, q)) if n else 0.0

        split: tuple[PartTiming, ...] = ()
        if n and (self._measured or bool(self._parts[:n].any())):
            measured = self._parts[:n] * 1e6
            columns = [measured[:, k] for k in range(MEASURED_PARTS)]
            columns.append(np.maximum(comp - measured.sum(axis=1), 0.0))
            split = tuple(
                PartTiming(name=name, p50_us=pct(col, 50), p99_us=pct(col, 99), max_us=float(col.max()))
                for name, col in zip(PARTS, columns, strict=True)
            )

        stalls, outside, off_max = 0, float(comp.max()) if n else 0.0, 0.0
        if n and (self._cpu_measured or bool(self._off_cpu[:n].any())):
            off = self._off_cpu[:n]
            stalled = off > STALL_OFF_CPU
            stalls = int(stalled.sum())
            outside = float(comp[~stalled].max()) if stalls < n else 0.0
            off_max = float(off.max()) * 1e6

        return TimingStats(
            pacing="realtime" if self.realtime else "fast",
            cycles=cycles,
            window=n,
            compute_p50_us=pct(comp, 50),
            compute_p99_us=pct(comp, 99),
            compute_max_us=float(comp.max()) if n else 0.0,
            lateness_p50_us=pct(late, 50),
            lateness_p99_us=pct(late, 99),
            lateness_max_us=float(late.max()) if n else 0.0,
            overruns=overruns,
            overrun_share=overruns / cycles if cycles else 0.0,
            max_consecutive_overruns=max_consecutive,
            sim_time=sim_time,
            setup=self.setup,
            control_law=self.control_law,
            plant=self.plant,
            long_cycles=int((comp > self.dt * 1e6).sum()) if n else 0,
            stalls=stalls,
            compute_max_outside_stalls_us=outside,
            off_cpu_max_us=off_max,
            worst_cycle=worst_cycle,
            worst_compute_us=float(self._worst[0]) * 1e6,
            parts=split,
        )


class Pacer:
    """Release times of a loop of period ``dt`` (s) on ``time.perf_counter``.

    Call ``begin`` at the start of each cycle (it returns the start time) and ``wait`` at its
    end. In real-time pacing cycle k is released at t₀ + k·``dt``: ``wait`` sleeps until
    ``spin`` s before the next release and busy-waits the rest (a sleeping CPU of a virtual
    machine wakes late); a loop more than one period behind skips ahead instead of catching up
    in a burst. Otherwise ``wait`` returns at once and each cycle is released when it starts.
    ``release`` is the current cycle's release time, for ``DeadlineMonitor.record``.

    ``pace(factor)`` switches at run time to pacing the simulation's time to at most ``factor``
    × wall time (ag_ex's watch, velma/executor/watch.py): ``wait(sim_time)`` returns once wall
    time has caught up with ``sim_time`` at that pace, measured from the first such wait; a
    loop more than ``dt`` behind goes on from now. It paces the simulation's time, not the
    cycles, since a loop attached to a world process in lockstep may see the world step twice
    in one of its cycles (velma/world/serve.py: the world steps with the command of the state
    before). ``pace(None)`` returns to the pacing it was built with."""

    def __init__(self, dt: float, *, realtime: bool, spin: float = 0.0) -> None:
        self.dt = dt
        self.realtime = realtime
        self.spin = spin
        self.release = time.perf_counter()
        self._built = (dt, realtime, spin)
        self._factor: float | None = None
        self._anchor: tuple[float, float] | None = None  # (wall s, simulation s) the pace counts from

    def _catch_up(self, sim_time: float, factor: float) -> None:
        """Sleep until wall time has caught up with ``sim_time`` at ``factor`` (class docstring)."""
        now = time.perf_counter()
        if self._anchor is None:
            self._anchor = (now, sim_time)
        wall0, sim0 = self._anchor
        self.release = wall0 + (sim_time - sim0) / factor
        if self.release > now:
            time.sleep(self.release - now)
        elif now - self.release > self.dt:
            self._anchor = (now, sim_time)  # behind: go on from now, no burst

    def pace(self, factor: float | None) -> None:
        """Release cycles at ``factor`` × wall time from now on (the busy-wait ``spin`` off: a
        slowed simulation is no hard-timing loop); None: the pacing given at construction. A
        pacer built real-time keeps its pacing. Raises ``ValueError`` for a factor that is not
        a finite number > 0."""
        dt, realtime, spin = self._built
        if factor is not None and not (factor > 0 and factor != float("inf")):
            raise ValueError(f"a pace is a finite factor > 0, not {factor}")
        self._factor = None if factor is None or realtime else factor
        self._anchor = None
        self.dt, self.realtime, self.spin = (dt, realtime, spin) if self._factor is None else (dt, True, 0.0)
        self.release = time.perf_counter()

    def begin(self) -> float:
        """Start a cycle; returns its start time (s)."""
        start = time.perf_counter()
        if not self.realtime:
            self.release = start
        return start

    def wait(self, sim_time: float | None = None) -> None:
        """End a cycle: in real-time pacing, return at the next release time; paced
        (``pace``), once wall time has caught up with ``sim_time`` (s)."""
        if not self.realtime:
            return
        if self._factor is not None and sim_time is not None:
            self._catch_up(sim_time, self._factor)
            return
        self.release += self.dt
        now = time.perf_counter()
        if self.release - self.spin > now:
            time.sleep(self.release - self.spin - now)
        if self.release > now:
            while time.perf_counter() < self.release:
                pass
        elif now - self.release > self.dt:
            self.release = now
