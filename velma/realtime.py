"""The real-time setup a process asks the OS for: SCHED_FIFO, a CPU of its own, and a CPU
wake-up latency of 0 µs (the PM QoS request that cyclictest also makes), and what it got.

ag_ex's 1 kHz control loop (velma/executor/loop_process.py) and the world process that steps
the robot's physics in real time (velma/world/main.py) both ask for it: the loop at
:data:`FIFO_PRIORITY` on the highest-numbered CPU it may use, the world at
:data:`WORLD_FIFO_PRIORITY` on the lowest (docs/bench/loop.md measures both placements). These
need privileges (CAP_SYS_NICE, write access to ``/dev/cpu_dma_latency``) that a container may
not grant: what was refused is reported, never raised.
"""

from __future__ import annotations

import os
import platform
import struct

import msgspec

FIFO_PRIORITY = 80
"""SCHED_FIFO priority of ag_ex's control loop (1..99), above threaded IRQ handlers (50)."""
WORLD_FIFO_PRIORITY = FIFO_PRIORITY - 1
"""SCHED_FIFO priority of the world process: just below the loop's, above everything else."""
PM_QOS_DEVICE = "/dev/cpu_dma_latency"
"""Linux's CPU latency PM QoS interface: while a process holds it open with a 32-bit latency
written to it, no CPU enters an idle state slower to leave than that (Linux
Documentation/power/pm_qos_interface.rst)."""
_held_qos: list[int] = []  # file descriptors of granted PM QoS requests, held until the process ends


class RealtimeSetup(msgspec.Struct, frozen=True, kw_only=True):
    """What the OS granted the calling process: ``policy`` (``SCHED_FIFO`` or ``SCHED_OTHER``),
    ``priority`` (FIFO priority, 0 for OTHER), ``cpus`` (the CPU set it may run on),
    ``pinned`` (True when the set was narrowed to one CPU), ``cpu_latency_us`` (the CPU
    wake-up latency held through PM QoS, None when not requested or refused), ``notes`` (why
    something was not granted)."""

    policy: str
    priority: int
    cpus: tuple[int, ...]
    pinned: bool
    notes: tuple[str, ...] = ()
    cpu_latency_us: int | None = None

    def describe(self) -> str:
        """One phrase for tables: e.g. ``SCHED_FIFO pinned, PM QoS 0 µs``."""
        text = f"{self.policy}{' pinned' if self.pinned else ''}"
        if self.cpu_latency_us is not None:
            text += f", PM QoS {self.cpu_latency_us} µs"
        return text


PR_SET_NAME = 15
"""prctl(2) option: the calling thread's name, which for a process's first thread is the name
``ps``, ``top`` and ``/proc/<pid>/comm`` show."""


def name_process(name: str) -> bool:
    """Name the calling process ``name`` (at most 15 bytes kept) for ``ps``/``top`` and
    ``/proc/<pid>/comm`` (e.g. ag_ex's children ``velma-loop`` and ``velma-camera``, which
    multiprocessing's spawn leaves all called ``python3``); call it from the main thread.
    Linux only: elsewhere, or if refused, returns False and changes nothing."""
    if platform.system() != "Linux":
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(PR_SET_NAME, name.encode()[:15], 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


def hold_cpu_latency(latency_us: int = 0) -> str | None:
    """Ask Linux to keep every CPU's wake-up latency ≤ ``latency_us`` (µs) until this process
    ends, by writing it to :data:`PM_QOS_DEVICE` and keeping that file open. Returns None when
    granted, else why not (one line). Never raises.

    Why (docs/bench/loop.md "CPU latency PM QoS"): an idle CPU otherwise halts; on a
    virtual machine a halted vCPU hands its physical core to the host, and the loop comes back
    to cold caches after every sleep. Held at 0 µs the idle CPU polls instead (the cpuidle POLL
    state) at the price of that CPU's power; cyclictest makes the same request by default."""
    if platform.system() != "Linux":
        return "PM QoS: not available on this OS"
    try:
        fd = os.open(PM_QOS_DEVICE, os.O_WRONLY)
    except OSError as exc:
        return f"PM QoS refused: {PM_QOS_DEVICE}: {exc.strerror}"
    try:
        os.write(fd, struct.pack("=i", latency_us))
    except OSError as exc:
        os.close(fd)
        return f"PM QoS refused: {exc.strerror}"
    _held_qos.append(fd)  # the request lasts as long as the file stays open
    return None


def enter_realtime(
    *,
    priority: int = FIFO_PRIORITY,
    cpu: int | None = None,
    pin: bool = True,
    cpu_latency_us: int | None = 0,
) -> RealtimeSetup:
    """Ask for SCHED_FIFO at ``priority``, if ``pin`` pin the calling process to ``cpu``
    (default: the highest-numbered CPU it may use), and unless ``cpu_latency_us`` is None hold
    the CPUs' wake-up latency at that many µs (:func:`hold_cpu_latency`). Never raises: what was
    refused is in ``notes``.

    A SCHED_FIFO task that never blocks would starve its CPU; the loop sleeps until each
    release time, so it uses only its compute time. Linux ignores timer slack for real-time
    tasks, which makes those sleeps precise (sched(7), prctl(2) PR_SET_TIMERSLACK)."""
    notes: list[str] = []
    policy, prio = "SCHED_OTHER", 0
    if platform.system() != "Linux" or not hasattr(os, "sched_setscheduler"):
        notes.append("SCHED_FIFO: not available on this OS")
    else:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
            policy, prio = "SCHED_FIFO", priority
        except OSError as exc:  # EPERM without CAP_SYS_NICE / rtprio limit
            notes.append(f"SCHED_FIFO refused: {exc.strerror}")
    cpus: tuple[int, ...] = ()
    pinned = False
    if hasattr(os, "sched_getaffinity"):
        allowed = sorted(os.sched_getaffinity(0))
        want = cpu if cpu is not None else allowed[-1]
        if not pin:
            notes.append("not pinned (by request)")
        elif len(allowed) > 1 and want in allowed:
            try:
                os.sched_setaffinity(0, {want})
                pinned = True
            except OSError as exc:
                notes.append(f"CPU affinity refused: {exc.strerror}")
        elif len(allowed) <= 1:
            notes.append("one CPU available: not pinned")
        cpus = tuple(sorted(os.sched_getaffinity(0)))
    else:
        notes.append("CPU affinity: not available on this OS")
    latency: int | None = None
    if cpu_latency_us is not None:
        refused = hold_cpu_latency(cpu_latency_us)
        if refused is None:
            latency = cpu_latency_us
        else:
            notes.append(refused)
    return RealtimeSetup(
        policy=policy, priority=prio, cpus=cpus, pinned=pinned, notes=tuple(notes), cpu_latency_us=latency
    )
