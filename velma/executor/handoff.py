"""Lock-free, bounded hand-offs between the control loop process and ag_ex's communication
side, in POSIX shared memory (``multiprocessing.shared_memory``).

- ``SpscRing``: a single-producer single-consumer ring of byte messages (commands one way,
  results the other). ``push`` never blocks: it returns False when the ring is full;
  ``pop`` returns None when it is empty. Capacity is fixed at creation (``slots`` messages of
  at most ``slot_size`` − 4 bytes).
- ``LatestValue``: one byte message overwritten by a single writer and read by any number of
  readers (a sequence lock: the writer makes the sequence odd while it writes; a reader
  retries while the sequence is odd or changed under it). The robot state crosses this way.

Neither takes a lock or makes a system call on ``push``/``pop``/``write``/``read``.

Every block is named as velma/shm.py says, and swept from there when its creator is gone.

Memory ordering: the producer writes a message before it advances the index (or the sequence
number) with an aligned 8-byte store; the consumer reads the index before the message.
x86-64 keeps stores in program order (TSO), which makes this correct there; on weakly ordered
CPUs (ARM) Python gives no fence, so a reader could see an index before the bytes it covers.
Layout: [head u64][pad to 64][tail u64][pad to 128][slot 0][slot 1]…; a slot is [len u32][bytes].
"""

from __future__ import annotations

import contextlib
import struct
from multiprocessing import shared_memory

import numpy as np
import numpy.typing as npt

from velma.shm import BLOCK_PREFIX, SHM_DIR, BlockError, new_block, remove_orphans, shared_view

__all__ = [
    "BLOCK_PREFIX",
    "SHM_DIR",
    "HandoffError",
    "LatestValue",
    "SpscRing",
    "new_block",
    "remove_orphans",
    "shared_view",
]

_HEADER = 128
_LEN = struct.Struct("<I")


def _attach(name: str) -> shared_memory.SharedMemory:
    """Open an existing block. A process started with multiprocessing's spawn shares its
    parent's resource tracker, so attaching there does not make the child unlink the block
    when it exits (for unrelated processes it would before Python 3.13: CPython gh-82300)."""
    return shared_memory.SharedMemory(name=name)


class HandoffError(BlockError):
    """A message does not fit its slot, or a shared block has the wrong size."""


class SpscRing:
    """Single-producer single-consumer ring of byte messages in shared memory (see module).

    Create with ``SpscRing.create(slots, slot_size)`` in one process and open the same ring
    with ``SpscRing.attach(name, slots, slot_size)`` in the other. The creator ``unlink``s."""

    def __init__(self, shm: shared_memory.SharedMemory, slots: int, slot_size: int) -> None:
        if shm.size < _HEADER + slots * slot_size:
            raise HandoffError(f"shared block {shm.name} is {shm.size} B, need {_HEADER + slots * slot_size}")
        self.shm = shm
        self.slots = slots
        self.slot_size = slot_size
        self._buf = shared_view(shm)
        self._head = np.ndarray((1,), dtype=np.uint64, buffer=self._buf, offset=0)
        self._tail = np.ndarray((1,), dtype=np.uint64, buffer=self._buf, offset=64)

    @classmethod
    def create(cls, slots: int = 64, slot_size: int = 65536) -> SpscRing:
        """A new, empty ring of ``slots`` messages of at most ``slot_size`` − 4 bytes."""
        if slots < 1 or slot_size <= _LEN.size:
            raise HandoffError(f"bad ring geometry: {slots} slots of {slot_size} B")
        shm = new_block(_HEADER + slots * slot_size)
        shared_view(shm)[:_HEADER] = bytes(_HEADER)
        return cls(shm, slots, slot_size)

    @classmethod
    def attach(cls, name: str, slots: int, slot_size: int) -> SpscRing:
        """The ring ``name`` created by another process with the same geometry."""
        return cls(_attach(name), slots, slot_size)

    @property
    def name(self) -> str:
        """The shared memory block's name (to ``attach`` from another process)."""
        return self.shm.name

    def __len__(self) -> int:
        return int(self._head[0]) - int(self._tail[0])

    def push(self, message: bytes) -> bool:
        """Append ``message`` (producer side). False when the ring is full (nothing written);
        raises ``HandoffError`` when the message is longer than a slot can hold."""
        n = len(message)
        if n > self.slot_size - _LEN.size:
            raise HandoffError(f"message of {n} B does not fit a {self.slot_size} B slot")
        head = int(self._head[0])
        if head - int(self._tail[0]) >= self.slots:
            return False
        off = _HEADER + (head % self.slots) * self.slot_size
        _LEN.pack_into(self._buf, off, n)
        self._buf[off + _LEN.size : off + _LEN.size + n] = message
        self._head[0] = head + 1
        return True

    def pop(self) -> bytes | None:
        """Remove and return the oldest message (consumer side), or None when empty."""
        tail = int(self._tail[0])
        if tail == int(self._head[0]):
            return None
        off = _HEADER + (tail % self.slots) * self.slot_size
        (n,) = _LEN.unpack_from(self._buf, off)
        out = bytes(self._buf[off + _LEN.size : off + _LEN.size + n])
        self._tail[0] = tail + 1
        return out

    def close(self) -> None:
        """Release this process's mapping (drop the numpy views first)."""
        del self._head, self._tail, self._buf
        self.shm.close()

    def unlink(self) -> None:
        """Remove the block from the system (creator, after both sides closed or exited)."""
        with contextlib.suppress(FileNotFoundError):
            self.shm.unlink()


class LatestValue:
    """One byte message with a single writer and many readers (a sequence lock, see module).

    ``read`` returns None before the first ``write`` or if the writer kept changing the value
    for ``retries`` attempts."""

    def __init__(self, shm: shared_memory.SharedMemory, capacity: int) -> None:
        if shm.size < _HEADER + capacity:
            raise HandoffError(f"shared block {shm.name} is {shm.size} B, need {_HEADER + capacity}")
        self.shm = shm
        self.capacity = capacity
        self._buf = shared_view(shm)
        self._seq = np.ndarray((1,), dtype=np.uint64, buffer=self._buf, offset=0)

    @classmethod
    def create(cls, capacity: int = 65536) -> LatestValue:
        """A new, empty value of at most ``capacity`` − 4 bytes."""
        shm = new_block(_HEADER + capacity)
        shared_view(shm)[:_HEADER] = bytes(_HEADER)
        return cls(shm, capacity)

    @classmethod
    def attach(cls, name: str, capacity: int) -> LatestValue:
        """The value ``name`` created by another process with the same capacity."""
        return cls(_attach(name), capacity)

    @property
    def name(self) -> str:
        return self.shm.name

    def block(self) -> tuple[npt.NDArray[np.uint8], int]:
        """The whole shared buffer (uint8, writable) and the byte offset of the value's
        length, for a writer outside Python that keeps this layout and protocol (the sequence
        number, u64, at byte 0; velma/control/_plant.hpp ``Plant.publish_state``)."""
        return np.frombuffer(self._buf, dtype=np.uint8), _HEADER

    @property
    def version(self) -> int:
        """How many writes have completed."""
        return int(self._seq[0]) // 2

    def write(self, message: bytes) -> None:
        """Replace the value (the single writer). Raises ``HandoffError`` if too long."""
        n = len(message)
        if n > self.capacity - _LEN.size:
            raise HandoffError(f"value of {n} B does not fit {self.capacity} B")
        seq = int(self._seq[0])
        self._seq[0] = seq + 1
        _LEN.pack_into(self._buf, _HEADER, n)
        self._buf[_HEADER + _LEN.size : _HEADER + _LEN.size + n] = message
        self._seq[0] = seq + 2

    def read(self, retries: int = 100) -> bytes | None:
        """A consistent copy of the value, or None (see class docstring)."""
        for _ in range(retries):
            s1 = int(self._seq[0])
            if s1 == 0:
                return None
            if s1 % 2:
                continue
            (n,) = _LEN.unpack_from(self._buf, _HEADER)
            if n > self.capacity - _LEN.size:
                continue
            out = bytes(self._buf[_HEADER + _LEN.size : _HEADER + _LEN.size + n])
            if int(self._seq[0]) == s1:
                return out
        return None

    def close(self) -> None:
        del self._seq, self._buf
        self.shm.close()

    def unlink(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.shm.unlink()
