"""The traffic tap (ROCO_TAP_DIR: what every bus puts) and the FSM record (each FSM transition
and reply-by time-out of an agent, in its run folder and the tap folder): what
``roco spec coverage`` counts from."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Arc, Behaviour
from services.runtime.fsm_record import FsmDeclared, FsmEntered, TimedOut, read_records, record_files
from services.runtime.memory_transport import MemoryBus
from services.runtime.tap import read_tap, tap_files
from shared.fipa_codec import Performative, decode, encode
from shared.fipa_codec.batch import pack
from shared.fipa_codec.languages.l_wm import ObjectQuery
from shared.settings import Settings
from tests.support.messages import communicate

KEY = "roco/fipa/C4/a_pl/a_km"


def test_no_tap_when_the_setting_is_unset(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(Settings.env_name("tap_dir"), raising=False)
    assert MemoryBus().tap is None


def test_a_bus_taps_each_communicate_of_a_batch_and_nothing_else(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(Settings.env_name("tap_dir"), str(tmp_path))
    one, two = (
        encode(communicate(Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", cid, ObjectQuery("jar")))
        for cid in ("q1", "q2")
    )
    bus, other = MemoryBus(), MemoryBus()
    bus.publish(KEY, pack([one, two]))
    bus.publish("roco/human/in", b"{}")
    other.publish(KEY, one)
    (path,) = tap_files(tmp_path)
    entries = list(read_tap(path, limit=1 << 20))
    assert [decode(e.payload).conversation_id for e in entries] == ["q1", "q2", "q1"]
    assert {e.key for e in entries} == {KEY}
    assert entries[0].group == entries[1].group != entries[2].group  # one group per bus
    with pytest.raises(ValueError, match="more than the 10 read"):
        list(read_tap(path, limit=10))


class Asker(Agent):
    """a_pl: asks a_km something nobody answers (reply-by 0.1 s), then goes from ``ask`` to
    ``done`` once the time-out's failure arrived."""

    name = "a_pl"
    period = 0.01

    def build_fsm(self) -> FSM:
        self.failed = threading.Event()
        return FSM(
            [
                Behaviour("ask", self._collect, terminal=self.failed.is_set),
                Behaviour("done", lambda: None, terminal=lambda: False),
            ],
            [Arc("ask", "done", label="answered")],
        )

    def setup(self) -> None:
        self.engine.send(
            "a_km", Performative.QUERY_REF, ObjectQuery("jar"), protocol="fipa-query", reply_by_s=0.1
        )

    def _collect(self) -> None:
        while self.engine.x:
            if self.engine.x.popleft().performative is Performative.FAILURE:
                self.failed.set()


def test_an_agent_records_its_fsm_its_transitions_and_its_time_outs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    run_dir, tap = tmp_path / "run", tmp_path / "tap"
    monkeypatch.setenv(Settings.env_name("run_dir"), str(run_dir))
    monkeypatch.setenv(Settings.env_name("tap_dir"), str(tap))
    agent = Asker(MemoryBus().transport())
    agent.engine.bind()
    t = threading.Thread(target=agent.engine.run, daemon=True)
    t.start()
    try:
        assert agent.failed.wait(5)
    finally:
        agent.engine.stop()
        t.join(timeout=5)
    for folder in (run_dir, tap):
        (path,) = record_files(folder)
        assert path.name.startswith("a_pl.")
        records = list(read_records(path))
        declared, start, timed_out, entered = records[:4]
        assert isinstance(declared, FsmDeclared) and declared.arcs == [("ask", "done", "answered")]
        assert declared.implementation == f"{__name__}:Asker" and declared.states == ["ask", "done"]
        assert isinstance(start, FsmEntered) and (start.state, start.how) == ("ask", "start")
        assert isinstance(timed_out, TimedOut)
        assert (timed_out.peer, timed_out.protocol, timed_out.state) == ("a_km", "fipa-query", "queried")
        assert isinstance(entered, FsmEntered)
        assert (entered.source, entered.state, entered.label, entered.how) == (
            "ask",
            "done",
            "answered",
            "arc",
        )
        assert len(records) == 4  # one record per transition, none per step
