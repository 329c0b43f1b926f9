"""The FRI-like link between the simulated robot's hardware (the world) and its controller
(ag_ex's 1 kHz loop): one block of POSIX shared memory; per cycle the robot's measured state
one way and the commanded torques and servo targets the other.

As on a KUKA LWR4+ under FRI (KUKA Fast Research Interface 1.0, "monitor" and "command"
modes), the controller gets the measured state of cycle k, answers with the command for
cycle k, and the robot side applies the latest command it has. The link itself is only
numbers and counters: what the numbers mean is the caller's layout.

Layout (native byte order, x86-64 little-endian; offsets in bytes):

====== ======================================================================================
0      magic ``ROCOLNK2`` (8 B), then ``n_measured``, ``n_command``, ``n_scene`` (u32 each)
64     measured: sequence lock (u64, odd while written), the world's cycle k (u64)
80     command: sequence lock (u64), the world cycle the command answers (u64)
96     doorbells (u32 each, futex words): world → controller, controller → world
112    scene: sequence lock (u64), the world's cycle (u64)
128    the world's timing counts, int64 × ``N_COUNTERS`` (velma/world/timing.py)
320    measured values, float64 × ``n_measured``
…      command values, float64 × ``n_command``
…      scene values, float64 × ``n_scene`` (may be none)
====== ======================================================================================

A value block is copied under its sequence lock (one writer each: the world writes the
measured state and the scene, the controller the command); a reader retries while the lock is
odd or moved. The timing counts are written by the world alone, slot by slot (aligned
8-byte stores, no lock): ``counters``. The scene is what the world shows beyond the robot's
own sensors (the head camera's capture is made from it); the controller reads it only when it
needs it.
A waiter spins on the counter for ``spin_s``, then sleeps on the doorbell (Linux futex,
shared between processes) until the writer rings it; so the cost of a hand-off is the
spin's when the other side answers quickly and one wake-up otherwise (measured by
``scripts/bench_link.py``). Nothing here takes a lock or allocates per cycle.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import struct
import time
from multiprocessing import resource_tracker, shared_memory

import numpy as np
import numpy.typing as npt

from velma.shm import BlockError, new_block, shared_view

MAGIC = b"ROCOLNK3"
COUNTERS_AT = 128
N_COUNTERS = 24
"""int64 slots for the world's timing counts (velma/world/timing.py ``N_SLOTS`` of them used)."""
HEADER = COUNTERS_AT + 8 * N_COUNTERS
_COUNTS = struct.Struct("<III")
_MEASURED_SEQ, _MEASURED_CYCLE, _COMMAND_SEQ, _COMMAND_CYCLE = 8, 9, 10, 11  # u64 word indices
_WORLD_BELL, _CONTROLLER_BELL = 24, 25  # u32 word indices (bytes 96, 100)
_SCENE_SEQ, _SCENE_CYCLE = 14, 15  # u64 word indices (bytes 112, 120)
READ_RETRIES = 10_000
"""Attempts of a read under a sequence lock held odd (a write takes < 1 µs; a writer killed
mid-write would leave it odd for good): then the read gives None, as before any write."""
NO_CYCLE = np.iinfo(np.uint64).max
"""The cycle counter's value before the first write."""

_SYS_FUTEX = 202  # x86-64
_FUTEX_WAIT, _FUTEX_WAKE = 0, 1  # shared between processes: no FUTEX_PRIVATE_FLAG


def _untrack(shm: shared_memory.SharedMemory) -> None:
    """Keep ``shm`` out of this process's resource tracker: the world removes its block in
    :meth:`RobotLink.close`, and an attaching controller must never remove it when it ends
    (before Python 3.13 its tracker would: CPython gh-82300). A block left by a killed world is
    swept as any other (velma/shm.py ``remove_orphans``)."""
    resource_tracker.unregister(getattr(shm, "_name", f"/{shm.name}"), "shared_memory")


class LinkError(BlockError):
    """A block that is not a link, or values of the wrong size."""


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Futex:
    """FUTEX_WAIT / FUTEX_WAKE on a u32 in shared memory (Linux, x86-64); where the system
    call is not there, waiting sleeps in 50 µs steps instead."""

    def __init__(self) -> None:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        self._syscall = libc.syscall if os.uname().machine == "x86_64" else None

    def wait(self, address: int, expected: int, timeout_s: float) -> None:
        """Sleep while the u32 at ``address`` holds ``expected``, at most ``timeout_s``."""
        if self._syscall is None:
            time.sleep(min(timeout_s, 50e-6))
            return
        ts = _Timespec(int(timeout_s), int((timeout_s % 1.0) * 1e9))
        self._syscall(_SYS_FUTEX, ctypes.c_void_p(address), _FUTEX_WAIT, expected, ctypes.byref(ts), None, 0)

    def wake(self, address: int) -> None:
        """Wake every process sleeping on the u32 at ``address``."""
        if self._syscall is not None:
            self._syscall(_SYS_FUTEX, ctypes.c_void_p(address), _FUTEX_WAKE, 0x7FFFFFFF, None, None, 0)


class RobotLink:
    """One link block (module docstring). The world makes it (:meth:`create`), the controller
    attaches to it by name (:meth:`attach`): a controller that restarts attaches to the same
    block and finds the world's latest measured state there."""

    def __init__(self, shm: shared_memory.SharedMemory, *, owner: bool) -> None:
        buf = shared_view(shm)
        if bytes(buf[:8]) != MAGIC:
            raise LinkError(f"shared block {shm.name} is not a robot link")
        self.n_measured, self.n_command, self.n_scene = _COUNTS.unpack_from(buf, 8)
        need = HEADER + 8 * (self.n_measured + self.n_command + self.n_scene)
        if shm.size < need:
            raise LinkError(f"shared block {shm.name} is {shm.size} B, the link needs {need}")
        self.shm, self.owner = shm, owner
        self._buf = buf
        self._u64 = np.ndarray((HEADER // 8,), dtype=np.uint64, buffer=buf)
        self._u32 = np.ndarray((HEADER // 4,), dtype=np.uint32, buffer=buf)
        self.counters = np.ndarray((N_COUNTERS,), dtype=np.int64, buffer=buf, offset=COUNTERS_AT)
        """The world's timing counts (velma/world/timing.py ``WorldClock.publish`` writes them,
        ``WorldTiming.read`` reads them; a view into the block)."""
        self._measured = np.ndarray((self.n_measured,), dtype=np.float64, buffer=buf, offset=HEADER)
        self._command = np.ndarray(
            (self.n_command,), dtype=np.float64, buffer=buf, offset=HEADER + 8 * self.n_measured
        )
        self._scene = np.ndarray(
            (self.n_scene,),
            dtype=np.float64,
            buffer=buf,
            offset=HEADER + 8 * (self.n_measured + self.n_command),
        )
        base = self._u32.ctypes.data
        self._world_bell = base + 4 * _WORLD_BELL
        self._controller_bell = base + 4 * _CONTROLLER_BELL
        self._futex = _Futex()

    @classmethod
    def create(cls, n_measured: int, n_command: int, n_scene: int = 0) -> RobotLink:
        """A new link for ``n_measured``, ``n_command`` and ``n_scene`` float64 values, nothing
        written yet. Raises OSError when the system refuses the block."""
        shm = new_block(HEADER + 8 * (n_measured + n_command + n_scene))
        _untrack(shm)
        buf = shared_view(shm)
        buf[:HEADER] = bytes(HEADER)
        buf[:8] = MAGIC
        _COUNTS.pack_into(buf, 8, n_measured, n_command, n_scene)
        link = cls(shm, owner=True)
        for at in (_MEASURED_CYCLE, _COMMAND_CYCLE, _SCENE_CYCLE):
            link._u64[at] = NO_CYCLE
        return link

    @classmethod
    def attach(cls, name: str) -> RobotLink:
        """The link block ``name`` made by the world. Raises FileNotFoundError when there is
        none, LinkError when the block is not a link."""
        shm = shared_memory.SharedMemory(name=name, create=False)
        _untrack(shm)
        return cls(shm, owner=False)

    @property
    def name(self) -> str:
        return self.shm.name

    # ---- the world's side ------------------------------------------------------------------
    def publish(self, cycle: int, values: npt.NDArray[np.float64]) -> None:
        """Write the measured state of world cycle ``cycle`` and ring the controller's bell."""
        self._write(self._measured, _MEASURED_SEQ, _MEASURED_CYCLE, cycle, values)
        self._u32[_WORLD_BELL] += np.uint32(1)
        self._futex.wake(self._world_bell)

    def publish_scene(self, cycle: int, values: npt.NDArray[np.float64]) -> None:
        """Write the scene of world cycle ``cycle`` (no bell: it is read on demand)."""
        self._write(self._scene, _SCENE_SEQ, _SCENE_CYCLE, cycle, values)

    def read_command(self, out: npt.NDArray[np.float64]) -> int | None:
        """Copy the latest command into ``out``; returns the world cycle it answers, or None
        before the first command (or while a killed writer left it half written)."""
        return self._read(self._command, _COMMAND_SEQ, _COMMAND_CYCLE, out)

    def command_cycle(self) -> int | None:
        """The world cycle the latest command answers, None before the first (one load, no
        copy: for the world to tell whether it will have to wait)."""
        c = self._u64[_COMMAND_CYCLE]
        return None if c == NO_CYCLE else int(c)

    def wait_command(self, cycle: int, timeout_s: float, spin_s: float) -> bool:
        """Wait until the command answering world cycle ``cycle`` (or a later one) is there;
        False when ``timeout_s`` passed first."""
        return self._wait(_COMMAND_CYCLE, cycle, self._controller_bell, _CONTROLLER_BELL, timeout_s, spin_s)

    # ---- the controller's side -------------------------------------------------------------
    def read_measured(self, out: npt.NDArray[np.float64]) -> int | None:
        """Copy the latest measured state into ``out``; returns its world cycle, or None
        before the world published one (or while a killed writer left it half written)."""
        return self._read(self._measured, _MEASURED_SEQ, _MEASURED_CYCLE, out)

    def read_scene(self, out: npt.NDArray[np.float64]) -> int | None:
        """Copy the latest scene into ``out``; returns its world cycle, or None before the
        world published one."""
        return self._read(self._scene, _SCENE_SEQ, _SCENE_CYCLE, out)

    def wait_measured(self, cycle: int, timeout_s: float, spin_s: float) -> bool:
        """Wait until the measured state of world cycle ``cycle`` (or a later one) is there;
        False when ``timeout_s`` passed first."""
        return self._wait(_MEASURED_CYCLE, cycle, self._world_bell, _WORLD_BELL, timeout_s, spin_s)

    def command(self, cycle: int, values: npt.NDArray[np.float64]) -> None:
        """Write the command answering world cycle ``cycle`` and ring the world's bell."""
        self._write(self._command, _COMMAND_SEQ, _COMMAND_CYCLE, cycle, values)
        self._u32[_CONTROLLER_BELL] += np.uint32(1)
        self._futex.wake(self._controller_bell)

    # ---- both ------------------------------------------------------------------------------
    def _write(
        self, block: npt.NDArray[np.float64], seq: int, at: int, cycle: int, values: npt.NDArray[np.float64]
    ) -> None:
        if values.shape != block.shape:
            raise LinkError(f"{values.shape[0]} values for a block of {block.shape[0]}")
        u64 = self._u64
        s = u64[seq]
        u64[seq] = s + np.uint64(1)
        block[:] = values
        u64[at] = cycle
        u64[seq] = s + np.uint64(2)

    def _read(
        self, block: npt.NDArray[np.float64], seq: int, at: int, out: npt.NDArray[np.float64]
    ) -> int | None:
        u64 = self._u64
        for _ in range(READ_RETRIES):  # bounded: a writer killed mid-write leaves the lock odd
            s1 = u64[seq]
            if s1 == 0:
                return None
            if s1 & np.uint64(1):
                continue
            out[:] = block
            cycle = int(u64[at])
            if u64[seq] == s1:
                return cycle
        return None

    def _wait(self, at: int, cycle: int, bell: int, bell_word: int, timeout_s: float, spin_s: float) -> bool:
        u64, u32 = self._u64, self._u32
        want = np.uint64(cycle)

        def there() -> bool:
            c = u64[at]
            return bool(c != NO_CYCLE and c >= want)

        now = time.perf_counter()
        spin_end, end = now + spin_s, now + timeout_s
        while True:
            if there():
                return True
            now = time.perf_counter()
            if now >= end:
                return False
            if now < spin_end:
                continue
            rung = int(u32[bell_word])
            if there():
                return True
            self._futex.wait(bell, rung, min(end - now, 0.01))

    def close(self) -> None:
        """Let go of the block (the owner also removes it)."""
        del self._u64, self._u32, self.counters, self._measured, self._command, self._scene, self._buf
        self.shm.close()
        if self.owner:
            # unlink() tells the tracker too: balance the unregister of create()
            resource_tracker.register(getattr(self.shm, "_name", f"/{self.shm.name}"), "shared_memory")
            with contextlib.suppress(FileNotFoundError):
                self.shm.unlink()
