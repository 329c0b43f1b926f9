"""ag_ex serves a_ta's watch (services/agents/executor/watching.py): a fipa-subscribe on C5
with an L_EX ``Watch`` is agreed and the executor asked to watch; each frame it observes is
informed to a_ta as an L_SD ``Observation`` naming the robot's power-on; ``cancel`` ends it
at the executor, as does a_ta's token disappearing; an executor that cannot watch makes ag_ex
refuse with the reason. The executor is a fake; a_ta is played on a MemoryBus."""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from services.agents.executor.agent import ExecutorAgent
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_ex import Watch
from shared.fipa_codec.languages.l_sd import Observation
from tests.agents.test_executor_power_cycle import linked_ag_ex, name_link
from tests.support.peer import Peer

TIMEOUT_S = 30.0
OnFrame = Callable[[Observation], None]


class WatchingFake:
    """An executor attached to world link ``world_link`` that records its watches; ``can``
    False: it cannot watch (as without the head camera)."""

    def __init__(self, world_link: str, can: bool = True) -> None:
        self.world_link = world_link
        self.can = can
        self.watches: queue.SimpleQueue[tuple[tuple[str, ...], float]] = queue.SimpleQueue()
        self.unwatched = threading.Event()
        self.on_frame: OnFrame | None = None

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def submit(self, command: Any, on_done: Any) -> None: ...
    def hold(self, why: str) -> bool:
        return True

    def watch(
        self, objects: tuple[str, ...], period_s: float, on_frame: Callable[[Observation], None]
    ) -> None:
        if not self.can:
            raise RuntimeError("a watch needs the head camera, not perception 'truth'")
        self.on_frame = on_frame
        self.watches.put((objects, period_s))

    def unwatch(self) -> None:
        self.unwatched.set()


Start = Callable[[bool], tuple[Peer, WatchingFake, Any]]
"""Starts ag_ex with a fake that can (True) or cannot watch; gives a_ta, the fake and a_ta's
liveliness token."""


@pytest.fixture
def served(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[Callable[[bool], tuple[Peer, WatchingFake, Any]]]:
    monkeypatch.setenv("ROCO_RUN_DIR", str(tmp_path))
    name_link(tmp_path, "psm_1")
    bus = MemoryBus()
    running: list[tuple[ExecutorAgent, threading.Thread]] = []

    def start(can: bool) -> tuple[Peer, WatchingFake, Any]:
        fake = WatchingFake("psm_1", can)

        class Ex(ExecutorAgent):
            def make_executor(self) -> Any:
                return fake

        a_ta = Peer(bus, "a_ta", "ag_ex", "C5")
        token = bus.transport()
        token.announce(keys.alive_key("a_ta"))
        agent = Ex(bus.transport())
        agent.engine.bind()
        thread = threading.Thread(target=agent.engine.run, daemon=True)
        thread.start()
        running.append((agent, thread))
        return a_ta, fake, token

    yield start
    for agent, thread in running:
        agent.engine.stop()
        thread.join(TIMEOUT_S)


def _content(msg: Communicate) -> object:
    return decode_content(msg.language, msg.content) if msg.language else msg.content.decode()


def test_a_watch_is_agreed_its_frames_informed_and_cancelled(
    served: Start,
) -> None:
    a_ta, fake, _ = served(True)
    a_ta.send(Performative.SUBSCRIBE, "fipa-subscribe", "watch-1", Watch(objects=("bowl",), period_s=0.25))
    assert a_ta.got.get(timeout=TIMEOUT_S).performative is Performative.AGREE
    assert fake.watches.get(timeout=TIMEOUT_S) == (("bowl",), 0.25)
    assert fake.on_frame is not None
    fake.on_frame(Observation(stamp=3.25, objects=()))  # as the delivery thread calls it
    inform = a_ta.got.get(timeout=TIMEOUT_S)
    assert inform.performative is Performative.INFORM and inform.conversation_id == "watch-1"
    assert _content(inform) == Observation(stamp=3.25, objects=(), world="psm_1")
    a_ta.send(Performative.CANCEL, "fipa-subscribe", "watch-1", Watch(objects=("bowl",), period_s=0.25))
    assert a_ta.got.get(timeout=TIMEOUT_S).performative is Performative.INFORM  # the cancel answered
    assert fake.unwatched.is_set()
    fake.on_frame(Observation(stamp=3.5, objects=()))  # a frame in flight when it ended: not told
    a_ta.send(Performative.SUBSCRIBE, "fipa-subscribe", "watch-2", Watch(period_s=0.5))
    assert a_ta.got.get(timeout=TIMEOUT_S).performative is Performative.AGREE  # next comes this one's


def test_a_watch_ends_when_a_ta_is_gone(served: Start) -> None:
    a_ta, fake, token = served(True)
    a_ta.send(Performative.SUBSCRIBE, "fipa-subscribe", "watch-1", Watch(period_s=0.25))
    assert a_ta.got.get(timeout=TIMEOUT_S).performative is Performative.AGREE
    token.close()  # a_ta's session ends
    assert fake.unwatched.wait(TIMEOUT_S)


def test_a_watch_that_cannot_be_made_is_refused_with_the_reason(
    served: Start,
) -> None:
    a_ta, _, _ = served(False)
    a_ta.send(Performative.SUBSCRIBE, "fipa-subscribe", "watch-2", Watch(period_s=0.25))
    refused = a_ta.got.get(timeout=TIMEOUT_S)
    assert refused.performative is Performative.REFUSE
    assert _content(refused) == "cannot watch: a watch needs the head camera, not perception 'truth'"


def test_after_a_power_cycle_the_new_loop_watches_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The world started anew (a new link): ag_ex's new executor is asked for the watch served,
    and its frames name the new power-on."""
    with linked_ag_ex(tmp_path, monkeypatch, WatchingFake) as (made, a_ta, _):
        first = made.get(timeout=TIMEOUT_S)
        a_ta.send(Performative.SUBSCRIBE, "fipa-subscribe", "watch-1", Watch(period_s=0.5))
        assert a_ta.got.get(timeout=TIMEOUT_S).performative is Performative.AGREE
        assert first.watches.get(timeout=TIMEOUT_S) == ((), 0.5)
        name_link(tmp_path, "psm_new")  # the world process started again
        second = made.get(timeout=TIMEOUT_S)
        assert second.watches.get(timeout=TIMEOUT_S) == ((), 0.5)
        assert second.on_frame is not None
        second.on_frame(Observation(stamp=0.5, objects=()))
        inform = a_ta.got.get(timeout=TIMEOUT_S)
        assert inform.conversation_id == "watch-1" and _content(inform) == Observation(
            stamp=0.5, objects=(), world="psm_new"
        )


class _Sink:
    """A viewer's robot sink that records whether its head camera was started."""

    def __init__(self) -> None:
        self.camera = threading.Event()

    def start_camera(self, source: Any, *, seed: int = 0, pose_seed: int | None = None) -> None:
        self.camera.set()

    def stop_camera(self, timeout: float = 10.0) -> None: ...
    def snapshot(self, snap: Any) -> None: ...
    def observation(self, obs: Any) -> None: ...
    def close(self) -> None: ...


class _Hooks:
    """A viewer's hooks (services/runtime/hooks.py) that do not want the head camera."""

    def __init__(self) -> None:
        self.sink = _Sink()

    def traffic(self, process: str, run_dir: Path | None = None) -> None:
        return None

    def robot(self, process: str) -> _Sink:
        return self.sink

    def queue(self, process: str) -> None:
        return None

    def camera_wanted(self) -> bool:
        return False


HOOKS = _Hooks()
"""Loaded by name (``ROCO_HOOKS``) in the next test."""


def test_a_viewer_that_wants_no_camera_gets_none_though_the_world_state_is_copied(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The loop copies the world state for the watch whenever the camera perceives; the
    viewer's head camera still starts only when its hooks want it."""
    monkeypatch.setenv("ROCO_HOOKS", f"{__name__}:HOOKS")
    monkeypatch.setenv("ROCO_RUN_DIR", str(tmp_path))
    name_link(tmp_path, "psm_1")
    fake = WatchingFake("psm_1")
    fake.world_state = True  # type: ignore[attr-defined]
    fake.world = lambda: None  # type: ignore[attr-defined]

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            return fake

    agent = Ex(MemoryBus().transport())
    agent.engine.bind()
    agent.setup()
    assert agent.rerun is HOOKS.sink and not HOOKS.sink.camera.is_set()
