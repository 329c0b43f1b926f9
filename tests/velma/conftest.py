"""Fixtures of the robot's tests: a world process (velma/world/) serving its robot link."""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator

import pytest

from velma.world.serve import world_process


@pytest.fixture
def world() -> Iterator[str]:
    """A world process in lockstep (spawned); its link's name. It must end cleanly."""
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe()
    proc = ctx.Process(target=world_process, args=(there,), kwargs={"realtime": False})
    proc.start()
    try:
        assert here.poll(120), "the world process said nothing"
        yield here.recv()
    finally:
        here.send("stop")
        proc.join(30)
    assert proc.exitcode == 0
