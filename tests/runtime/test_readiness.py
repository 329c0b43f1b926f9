"""An agent's readiness (services/runtime/engine.py ``Engine.ready``) and its ready file
(shared/ready_file.py, ``ROCO_READY_FILE``: what a container's health check reads): not ready
before its roles are set up and the agents it asks are seen, ready after, once. The agent runs
on the test's thread (``Engine.drive``), on an in-memory bus."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.runtime import keys
from services.runtime.main import ready_file
from services.runtime.memory_transport import MemoryBus
from services.spec.model import asked, default_spec
from shared.ready_file import clear, mark
from tests.runtime.test_agent_runtime import Counter

READY_LINE = "a_km ready: roles set up; a_ta seen\n"


def ready_agent(bus: MemoryBus, path: Path) -> tuple[Counter, list[str]]:
    """a_km (it asks a_ta) on ``bus``, bound, writing ``path`` when ready; and the lines it
    said it was ready with."""
    agent = Counter(bus.transport())
    said: list[str] = []

    def on_ready(line: str) -> None:
        said.append(line)
        mark(path, line)

    agent.engine.on_ready = on_ready
    agent.engine.bind()
    return agent, said


def test_the_agents_each_agent_asks_are_the_other_ends_of_what_it_initiates() -> None:
    spec = default_spec()
    shipped = {
        "a_km": ("a_ta",),  # C6: a_km subscribes to a_ta's states
        "a_pl": ("a_km",),
        "a_co": ("a_ta", "a_pl"),
        "ag_ex": (),
        "a_ta": ("ag_ex", "a_km"),
        "a_hi": ("a_co", "a_km"),  # not x_fipa (C8): an external role, not an agent
    }
    # the shipped agents (one added since asks the other ends of what it initiates, as these do)
    assert {a: asked(spec, a) for a in spec.launch_order if a in shipped} == shipped


def test_not_ready_until_set_up_and_the_agents_it_asks_are_seen(tmp_path: Path) -> None:
    bus, path = MemoryBus(), tmp_path / "ready"
    agent, said = ready_agent(bus, path)
    assert agent.engine.asks == ("a_ta",)
    bus.announce(keys.alive_key("a_pl"))  # an agent a_km does not ask
    assert not agent.engine.ready and not path.exists()  # not set up yet
    agent.engine.drive()  # setup, the liveliness token, the first behaviour until it blocks
    assert keys.alive_key("a_km") in bus.alive() and "a_pl" in agent.peers
    assert not agent.engine.ready and not path.exists()  # a_ta not seen
    bus.announce(keys.alive_key("a_ta"))
    agent.engine.drive()
    assert agent.engine.ready and path.read_text() == READY_LINE
    bus.withdraw(keys.alive_key("a_ta"))  # gone and back: still ready, said once
    bus.announce(keys.alive_key("a_ta"))
    agent.engine.drive()
    assert agent.engine.ready and said == [READY_LINE.strip()]
    agent.engine.stop()
    assert agent.engine.drive() is None


@pytest.mark.parametrize("name", ["a_km", "ag_ex"])
def test_ready_only_once_set_up(tmp_path: Path, name: str) -> None:
    """Ready comes after the agent's setup and its liveliness token, even with every agent it
    asks there from the start (a_km: a_ta), or when it asks none (ag_ex)."""
    bus, path = MemoryBus(), tmp_path / "ready"
    bus.announce(keys.alive_key("a_ta"))
    order: list[str] = []

    class SettingUp(Counter):
        def setup(self) -> None:
            order.append(f"setup, ready file there: {path.exists()}")

    SettingUp.name = name
    agent = SettingUp(bus.transport())

    def on_ready(line: str) -> None:
        order.append(f"ready, token there: {keys.alive_key(name) in bus.alive()}")
        mark(path, line)

    agent.engine.on_ready = on_ready
    agent.engine.bind()
    assert not agent.engine.ready and not path.exists()
    agent.engine.drive()
    assert order == ["setup, ready file there: False", "ready, token there: True"]
    line = READY_LINE if name == "a_km" else "ag_ex ready: roles set up\n"
    assert agent.engine.ready and path.read_text() == line
    agent.engine.stop()
    agent.engine.drive()


def test_the_ready_file_is_written_whole_and_cleared(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "ready"
    assert mark(path, "a_x ready\nsecond line") is None
    assert path.read_text() == "a_x ready second line\n"
    assert [p.name for p in tmp_path.iterdir()] == ["ready"]  # no temporary file left
    # a process's start: the file a killed one left is removed (ROCO_READY_FILE)
    monkeypatch.setenv("ROCO_READY_FILE", str(path))
    assert ready_file() == path and not path.exists()
    clear(path)  # absent: nothing to do
    monkeypatch.delenv("ROCO_READY_FILE")
    assert ready_file() is None
    assert mark(None, "nowhere") is None
    clear(None)
    why = mark(tmp_path / "missing" / "ready", "a_x ready")  # a process goes on without it
    assert why == f"cannot write the ready file {tmp_path / 'missing' / 'ready'}: No such file or directory"
