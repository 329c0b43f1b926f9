"""ag_ex when the robot is power-cycled (services/agents/executor/agent.py): the world names a
new link in the run folder, ag_ex ends the loop of the old world and attaches a new one by
itself, tells a_ta's subscription the new power-on, and its answers name the world they come
from (velma/world/files.py ``LinkWatch``)."""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import pytest

from services.agents.executor.agent import ExecutorAgent
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Performative
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_ex import CommandResult, PowerOn, PowerOns, Wait
from tests.support.peer import Peer
from velma.world.files import LINK_FILE, LinkWatch, write_whole

TIMEOUT_S = 30.0


def name_link(run_dir: Path, name: str) -> None:
    write_whole(run_dir / LINK_FILE, (name + "\n").encode())


F = TypeVar("F")


@contextlib.contextmanager
def linked_ag_ex(
    run_dir: Path, monkeypatch: pytest.MonkeyPatch, fake: Callable[[str], F]
) -> Iterator[tuple[queue.SimpleQueue[F], Peer, ExecutorAgent]]:
    """ag_ex on a MemoryBus in ``run_dir`` attached to a world named ``psm_old``, each executor
    it makes ``fake(world link)``: yields the executors as they are made, a_ta's end of C5 and
    the agent; the agent is stopped after, and its thread joined."""
    monkeypatch.setenv("ROCO_RUN_DIR", str(run_dir))
    name_link(run_dir, "psm_old")
    made: queue.SimpleQueue[F] = queue.SimpleQueue()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            executor = fake(self._world_link())
            made.put(executor)
            return executor

    bus = MemoryBus()
    a_ta = Peer(bus, "a_ta", "ag_ex", "C5")
    agent = Ex(bus.transport())
    agent.engine.bind()
    thread = threading.Thread(target=agent.engine.run, daemon=True)
    thread.start()
    try:
        yield made, a_ta, agent
    finally:
        agent.engine.stop()
        thread.join(TIMEOUT_S)


def test_the_watch_tells_a_new_link_once_and_not_a_world_that_is_away(tmp_path: Path) -> None:
    now = [0.0]
    watch = LinkWatch(tmp_path, "psm_old", period_s=0.5, clock=lambda: now[0])
    name_link(tmp_path, "psm_old")
    now[0] = 1.0
    assert watch.renewed() is None  # the same world
    (tmp_path / LINK_FILE).unlink()  # the world stopped: away, not renewed
    now[0] = 2.0
    assert watch.renewed() is None
    name_link(tmp_path, "psm_new")
    now[0] = 2.1
    assert watch.renewed() is None  # read at most every period
    now[0] = 2.5
    assert watch.renewed() == "psm_new" and watch.current == "psm_new"
    now[0] = 3.0
    assert watch.renewed() is None  # told once


class LinkedFake:
    """An executor attached to world link ``world_link``: answers each command at once."""

    def __init__(self, world_link: str) -> None:
        self.world_link = world_link
        self.started = threading.Event()
        self.stopped = threading.Event()

    def start(self) -> None:
        self.started.set()

    def stop(self) -> None:
        self.stopped.set()

    def submit(self, command: Any, on_done: Any) -> object:
        on_done(CommandResult(command="wait", ok=True, sim_time=1.0))
        return object()


def test_ag_ex_reattaches_to_a_world_started_anew_and_names_it_in_its_answers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with linked_ag_ex(tmp_path, monkeypatch, LinkedFake) as (made, a_ta, agent):
        first = made.get(timeout=TIMEOUT_S)
        assert first.started.wait(TIMEOUT_S)

        def answer(cid: str) -> CommandResult:
            a_ta.send(Performative.REQUEST, "fipa-request", cid, Wait(duration=1.0))
            reply = a_ta.got.get(timeout=TIMEOUT_S)
            assert reply.performative is Performative.INFORM and reply.language is not None
            content = decode_content(reply.language, reply.content)
            assert isinstance(content, CommandResult)
            return content

        def told() -> PowerOn:
            inform = a_ta.got.get(timeout=TIMEOUT_S)
            assert inform.performative is Performative.INFORM and inform.language is not None
            content = decode_content(inform.language, inform.content)
            assert isinstance(content, PowerOn)
            return content

        a_ta.send(Performative.SUBSCRIBE, "fipa-subscribe", "power-ons", PowerOns())
        assert a_ta.got.get(timeout=TIMEOUT_S).performative is Performative.AGREE
        assert told() == PowerOn(world="psm_old")  # the current power-on, at once
        assert answer("before").world == "psm_old"
        name_link(tmp_path, "psm_new")  # the world process started again: a new link
        second = made.get(timeout=TIMEOUT_S)
        assert first.stopped.wait(TIMEOUT_S) and second.started.wait(TIMEOUT_S)
        assert second.world_link == "psm_new"
        assert told() == PowerOn(world="psm_new")  # told before any command
        assert answer("after").world == "psm_new"
        assert agent.counters["world_restarts"] == 1
