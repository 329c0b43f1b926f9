"""ag_ex's camera feed (velma/executor/camera_feed.py, services/agents/executor/camera_feed.py):
nothing is rendered while nobody wants frames, frames come at most at the rate asked, and over
Zenoh the publisher's matching status alone switches the rendering on and off. A stand-in camera
counts its renders (no GL needed)."""

from __future__ import annotations

import queue
from collections.abc import Iterator

import msgspec
import numpy as np
import pytest

from services.agents.executor.camera_feed import CameraPublisher
from services.runtime import keys
from services.runtime.session import open_client
from tests.support.camera import Made, World
from tests.support.router import embedded_router
from velma.executor.camera_feed import SIZE, CameraFeed, CameraFrame

TIMEOUT = 20.0


def test_nothing_is_rendered_while_nobody_wants_frames() -> None:
    world, made, put = World(), Made(), queue.SimpleQueue[bytes]()
    feed = CameraFeed(world, put.put, made, rate_hz=200.0)
    try:
        assert feed.idle.wait(TIMEOUT), "the feed never waited for someone to want frames"
        assert (made.cameras, world.reads, feed.frames) == ([], 0, 0)
        feed.want(True)
        frames = [msgspec.msgpack.decode(put.get(timeout=TIMEOUT), type=CameraFrame) for _ in range(2)]
        feed.want(False)
        assert feed.idle.wait(TIMEOUT), "the feed went on after nobody wanted frames"
        reads, renders = world.reads, made.cameras[0].renders
        assert feed.frames == renders >= 2
        feed.want(True)  # wanted again: the same camera renders on
        put.get(timeout=TIMEOUT)
        assert world.reads > reads and len(made.cameras) == 1
    finally:
        feed.stop()
    assert made.cameras[0].closed
    f = frames[1]
    assert (f.width, f.height, f.encoding, len(f.data)) == (320, 240, "rgb8", 320 * 240 * 3)
    assert f.stamp == pytest.approx(0.1)
    assert (f.cx, f.cy) == (160.0, 120.0) and f.fx == f.fy == pytest.approx(120 / np.tan(np.radians(21.5)))


def test_the_rate_is_bounded_and_checked() -> None:
    with pytest.raises(ValueError, match="> 0 Hz"):
        CameraFeed(World(), lambda b: None, Made(), rate_hz=0.0)
    feed = CameraFeed(World(), lambda b: None, Made(), rate_hz=1000.0)
    feed.stop()
    assert feed.period_s == pytest.approx(1 / 30)


@pytest.fixture(scope="module")
def endpoint(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    yield from embedded_router(tmp_path_factory, "camera_feed")


def test_ag_ex_renders_only_while_a_subscriber_matches_its_key(endpoint: str) -> None:
    made = Made()
    ag_ex = open_client(endpoint)
    viewer = open_client(endpoint)
    publisher = CameraPublisher(ag_ex, World(), 50.0, make_camera=made)
    try:
        assert publisher.feed.idle.wait(TIMEOUT)
        assert made.cameras == []  # no subscriber yet: nothing made, nothing rendered
        got: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        sub = viewer.declare_subscriber(keys.camera_key("ag_ex"), lambda s: got.put(s.payload.to_bytes()))
        frame = msgspec.msgpack.decode(got.get(timeout=TIMEOUT), type=CameraFrame)
        assert (frame.width, frame.height) == SIZE
        publisher.feed.idle.clear()
        sub.undeclare()
        assert publisher.feed.idle.wait(TIMEOUT), "still rendering after the subscriber left"
    finally:
        publisher.close()
        viewer.close()
        ag_ex.close()
