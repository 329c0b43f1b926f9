"""The lock-free hand-offs of the executor (velma/executor/handoff.py): ring order, bounds,
oversize messages, the sequence-locked latest value, a crossing between two processes, and
the blocks of a killed creator removed by the next one."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support.fresh import run_python
from velma.executor.handoff import (
    BLOCK_PREFIX,
    SHM_DIR,
    HandoffError,
    LatestValue,
    SpscRing,
    new_block,
    remove_orphans,
)


@pytest.fixture
def ring() -> Iterator[SpscRing]:
    r = SpscRing.create(slots=4, slot_size=64)
    yield r
    r.close()
    r.unlink()


def test_ring_is_fifo_and_bounded(ring: SpscRing) -> None:
    assert ring.pop() is None
    for i in range(4):
        assert ring.push(bytes([i]) * (i + 1))
    assert len(ring) == 4
    assert not ring.push(b"x")  # full: refused, nothing overwritten
    assert [ring.pop() for _ in range(4)] == [b"\x00", b"\x01" * 2, b"\x02" * 3, b"\x03" * 4]
    assert ring.pop() is None
    # wraps around many times without losing order
    for i in range(50):
        assert ring.push(i.to_bytes(2, "little"))
        assert ring.pop() == i.to_bytes(2, "little")


def test_ring_rejects_oversize(ring: SpscRing) -> None:
    assert ring.push(b"a" * 60)
    with pytest.raises(HandoffError, match="does not fit"):
        ring.push(b"a" * 61)
    assert len(ring) == 1


def test_attach_checks_geometry(ring: SpscRing) -> None:
    with pytest.raises(HandoffError, match="need"):
        SpscRing.attach(ring.name, slots=400, slot_size=64)


def test_latest_value() -> None:
    v = LatestValue.create(capacity=32)
    try:
        assert v.read() is None and v.version == 0
        v.write(b"first")
        v.write(b"second")
        assert v.read() == b"second" and v.version == 2
        with pytest.raises(HandoffError):
            v.write(b"x" * 29)
        assert v.read() == b"second"
    finally:
        v.close()
        v.unlink()


def _echo(commands: str, results: str, n: int) -> None:
    inbox = SpscRing.attach(commands, 8, 128)
    outbox = SpscRing.attach(results, 8, 128)
    got = 0
    while got < n:
        msg = inbox.pop()
        if msg is None:
            continue
        while not outbox.push(msg[::-1]):
            pass
        got += 1
    inbox.close()
    outbox.close()


def test_rings_cross_processes() -> None:
    """A spawned process reverses 200 messages; order and content survive both rings."""
    commands = SpscRing.create(8, 128)
    results = SpscRing.create(8, 128)
    proc = multiprocessing.get_context("spawn").Process(target=_echo, args=(commands.name, results.name, 200))
    proc.start()
    try:
        sent = received = 0
        out: list[bytes] = []
        while received < 200:
            if sent < 200 and commands.push(f"message {sent}".encode()):
                sent += 1
            msg = results.pop()
            if msg is None and not proc.is_alive() and len(results) == 0:
                pytest.fail(f"echo process ended early with code {proc.exitcode}")
            if msg is not None:
                out.append(msg)
                received += 1
        proc.join(30)
        assert proc.exitcode == 0
        assert out == [f"message {i}".encode()[::-1] for i in range(200)]
    finally:
        if proc.is_alive():
            proc.kill()
        for r in (commands, results):
            r.close()
            r.unlink()


def _dead_pid() -> int:
    """The PID of a process that has ended (and been waited for)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait(timeout=60)
    return proc.pid


def test_a_block_is_named_after_its_creator() -> None:
    shm = new_block(256)
    try:
        assert shm.name.startswith(f"{BLOCK_PREFIX}{os.getpid()}_")
        assert shm.size >= 256
    finally:
        shm.close()
        shm.unlink()


def test_only_blocks_of_creators_that_are_gone_are_removed(tmp_path: Path) -> None:
    dead = _dead_pid()
    names = {
        "orphan": f"{BLOCK_PREFIX}{dead}_0123abcd",
        "live": f"{BLOCK_PREFIX}{os.getpid()}_0123abcd",
        "other": "psm_0123abcd",  # another program's block (multiprocessing's default names)
        "odd": f"{BLOCK_PREFIX}notapid_0123abcd",
    }
    for name in names.values():
        (tmp_path / name).write_bytes(b"x")
    assert remove_orphans(tmp_path) == [names["orphan"]]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(v for k, v in names.items() if k != "orphan")
    assert remove_orphans(tmp_path / "missing") == []


KILLED_CREATOR = """
import os, signal
from multiprocessing import resource_tracker
from velma.executor.handoff import LatestValue
value = LatestValue.create(4096)
value.write(b"left behind")
# as when the resource tracker dies with its process (a process group killed): nobody unlinks
resource_tracker.unregister("/" + value.name, "shared_memory")
print(value.name, flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


@pytest.mark.skipif(not SHM_DIR.is_dir(), reason="POSIX shared memory in /dev/shm (Linux)")
def test_the_blocks_of_a_killed_creator_are_removed_from_dev_shm() -> None:
    done = run_python(KILLED_CREATOR)
    assert done.returncode == -9, done.stderr[-2000:]
    name = done.stdout.strip()
    assert (SHM_DIR / name).exists()  # the leak this guards against
    assert name in remove_orphans()
    assert not (SHM_DIR / name).exists()
