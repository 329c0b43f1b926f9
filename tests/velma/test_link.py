"""The world/controller link (velma/world/link.py): values each way under sequence locks, the
cycle counters, waiting on the futex doorbells across processes, and a controller that
attaches again finding the world's latest state."""

from __future__ import annotations

import multiprocessing
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory

import numpy as np
import pytest

from velma.shm import SHM_DIR
from velma.world.link import LinkError, RobotLink

CYCLES = 200


def answer(name: str, cycles: int, conn: Connection) -> None:
    """A controller in a process of its own: per world cycle, the command is the state + 1."""
    link = RobotLink.attach(name)
    measured, command = np.zeros(link.n_measured), np.zeros(link.n_command)
    conn.send("attached")
    for k in range(cycles):
        if not link.wait_measured(k, 10.0, spin_s=0.0):
            conn.send(f"no state for cycle {k}")
            return
        assert link.read_measured(measured) == k
        command[:] = measured[: link.n_command] + 1.0
        link.command(k, command)
    link.close()
    conn.send("done")


def test_values_cross_with_their_cycle_and_nothing_before_the_first_write() -> None:
    world = RobotLink.create(3, 2)
    controller = RobotLink.attach(world.name)
    try:
        out3, out2 = np.zeros(3), np.zeros(2)
        assert controller.read_measured(out3) is None and world.read_command(out2) is None
        assert not controller.wait_measured(0, 0.02, spin_s=0.0)
        world.publish(7, np.array([1.0, 2.0, 3.0]))
        assert controller.wait_measured(7, 0.0, spin_s=0.0)
        assert controller.read_measured(out3) == 7 and out3.tolist() == [1.0, 2.0, 3.0]
        assert not controller.wait_measured(8, 0.02, spin_s=0.0)
        controller.command(7, np.array([4.0, 5.0]))
        assert world.wait_command(7, 0.0, spin_s=0.0)
        assert world.read_command(out2) == 7 and out2.tolist() == [4.0, 5.0]
        with pytest.raises(LinkError, match="2 values for a block of 3"):
            world.publish(8, np.zeros(2))
    finally:
        controller.close()
        world.close()


def test_a_controller_that_attaches_again_finds_the_latest_state_and_the_block_stays() -> None:
    world = RobotLink.create(2, 1)
    try:
        first = RobotLink.attach(world.name)
        world.publish(41, np.array([0.5, 0.25]))
        first.close()  # the controller ends: the world's block stays
        assert (SHM_DIR / world.name).exists()
        again = RobotLink.attach(world.name)
        out = np.zeros(2)
        assert again.read_measured(out) == 41 and out.tolist() == [0.5, 0.25]
        again.close()
    finally:
        name = world.name
        world.close()
    assert not (SHM_DIR / name).exists()  # the world removes it
    with pytest.raises(FileNotFoundError):
        RobotLink.attach(name)


def test_a_block_that_is_not_a_link_is_refused() -> None:
    other = SharedMemory(create=True, size=256)
    try:
        with pytest.raises(LinkError, match="not a robot link"):
            RobotLink.attach(other.name)
    finally:
        other.close()
        other.unlink()


def test_lockstep_across_processes_wakes_on_the_doorbells() -> None:
    world = RobotLink.create(4, 2)
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe()
    proc = ctx.Process(target=answer, args=(world.name, CYCLES, there))
    proc.start()
    try:
        assert here.poll(60) and here.recv() == "attached"
        command = np.zeros(2)
        for k in range(CYCLES):
            world.publish(k, np.full(4, float(k)))
            # no spinning: every hand-off sleeps on the futex until the other side rings
            assert world.wait_command(k, 10.0, spin_s=0.0), f"no command for cycle {k}"
            assert world.read_command(command) == k
            assert command.tolist() == [k + 1.0, k + 1.0]
        assert here.poll(10) and here.recv() == "done"
    finally:
        proc.join(10)
        world.close()
    assert proc.exitcode == 0


def test_a_write_left_half_done_reads_as_nothing_instead_of_hanging() -> None:
    world = RobotLink.create(2, 1)
    controller = RobotLink.attach(world.name)
    try:
        world.publish(3, np.array([1.0, 2.0]))
        world._u64[8] += np.uint64(1)  # the measured block's lock held odd: a writer killed mid-write
        assert controller.read_measured(np.zeros(2)) is None
    finally:
        controller.close()
        world.close()
