"""ag_ex's communication side: it holds the robot when a_ta's liveliness token goes away, and
publishes the robot state (services/agents/executor/agent.py)."""

from __future__ import annotations

import queue
import threading
from typing import Any

import msgspec

from services.agents.executor.agent import ExecutorAgent
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec.languages.l_ex import CommandResult
from velma.executor.state import RobotSnapshot


class HoldingFake:
    """Records ``hold`` calls; reports a fixed state."""

    def __init__(self) -> None:
        self.holds: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.holding: str | None = None

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def submit(self, command: Any, on_done: Any) -> None: ...

    def hold(self, why: str) -> bool:
        self.holding = why
        self.holds.put(why)
        return True

    def snapshot(self) -> RobotSnapshot:
        return RobotSnapshot(
            sim_time=1.0,
            joints={"torso_0_joint": 0.0},
            grip={},
            held={"left": True},
            held_object={"left": "jar"},
            holding=self.holding,
        )


def test_holds_when_a_ta_disappears_and_publishes_state() -> None:
    bus = MemoryBus()
    fake = HoldingFake()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            return fake

    states: queue.SimpleQueue[RobotSnapshot] = queue.SimpleQueue()
    dec = msgspec.msgpack.Decoder(RobotSnapshot)
    bus.subscribe(keys.state_key("ag_ex"), lambda _k, p: states.put(dec.decode(p)))
    a_ta = bus.transport()
    a_ta.announce(keys.alive_key("a_ta"))
    agent = Ex(bus.transport())
    assert agent.commanders == ("a_ta",)  # from the specification's C5
    agent.engine.bind()
    thread = threading.Thread(target=agent.engine.run, daemon=True)
    thread.start()
    try:
        first = states.get(timeout=10)
        assert first.holding is None and first.held_object == {"left": "jar"}
        assert fake.holds.empty()
        a_ta.close()  # a_ta's session ends: its token is withdrawn
        assert fake.holds.get(timeout=10) == "a_ta lost"
        state = states.get(timeout=10)
        while state.holding is None:
            state = states.get(timeout=10)
        assert state.holding == "a_ta lost"
        assert agent.counters["holds"] == 1
    finally:
        agent.engine.stop()
        thread.join(10)


def test_malformed_seed_is_a_clear_configuration_error(monkeypatch: Any) -> None:
    import pytest

    monkeypatch.setenv("ROCO_SEED", "abc")
    with pytest.raises(ValueError, match="ROCO_SEED='abc' is not an integer"):
        ExecutorAgent(MemoryBus().transport())
    monkeypatch.setenv("ROCO_SEED", "1")
    monkeypatch.setenv("ROCO_POSE_SEED", "-3")
    with pytest.raises(ValueError, match="ROCO_POSE_SEED=-3 is negative"):
        ExecutorAgent(MemoryBus().transport())


class LedgerFake(HoldingFake):
    """Runs each command at once, reporting its start and end as ``ExecutorProcess`` does
    (``on_start``, ``on_end``, before ``on_done``); ``twice``: the loop runs each command twice
    (a planted fault) and answers once."""

    def __init__(self, twice: bool = False) -> None:
        super().__init__()
        self.on_start: Any = None
        self.on_end: Any = None
        self.twice = twice

    def submit(self, command: Any, on_done: Any) -> Any:
        token = object()
        for k in range(2 if self.twice else 1):
            self.on_start(token, "wait", 1.0 + k)
            self.on_end(token, "wait", 1.5 + k, "ok")
        on_done(CommandResult(command="wait", ok=True, sim_time=1.5))
        return token


class CountingFake(HoldingFake):
    """Runs each command at once as ``ExecutorProcess`` reports it (``on_start``, ``on_end``
    with the result, then ``on_done``) and counts the runs by command name (``ran``); ``replay``
    renders a WorldCapture as an Observation at its stamp (``replays``)."""

    def __init__(self) -> None:
        super().__init__()
        self.on_start: Any = None
        self.on_end: Any = None
        self.ran: list[str] = []
        self.replays: list[str] = []

    def submit(self, command: Any, on_done: Any) -> Any:
        from shared.fipa_codec.languages.l_ex import command_name

        token, name = object(), command_name(command)
        self.ran.append(name)
        result = CommandResult(command=name, ok=True, reason="ran here", sim_time=9.0)
        self.on_start(token, name, 8.0)
        self.on_end(token, name, 9.0, "ok", result)
        on_done(result)
        return token

    def replay(self, name: str, result: Any, on_done: Any) -> Any:
        from shared.fipa_codec.languages.l_sd import Observation

        self.replays.append(name)
        on_done(Observation(stamp=result.stamp, objects=()))
        return object()


def test_a_restarted_ag_ex_answers_a_command_that_ended_before_from_the_ledger(
    monkeypatch: Any, tmp_path: Any
) -> None:
    """An earlier ag_ex's loop ended x's grasp (no contact), y's observe (a capture, not yet
    rendered when it stopped) and z's wait (a CommandResult too long for the line, kept in the
    side store); v's wait was cut short by its stop (``failure: stopped``) and w's started
    without an end. A restarted ag_ex answers x, y and z
    from the ledger without running them (a ``replayed`` line each), and runs v and w again (resumed).
    Planted: the ledger lookup disabled: the loop runs x again, and the judge says executed
    twice."""
    from services.report.ledger import _started_twice
    from services.spec.names import FIPA_REQUEST
    from shared.fipa_codec import Performative
    from shared.fipa_codec.languages import decode_content
    from shared.fipa_codec.languages.l_ex import Arm, Grasp, Observe, Wait
    from shared.fipa_codec.languages.l_sd import Observation
    from tests.support.peer import Peer, running
    from velma.executor.capture import WorldCapture
    from velma.executor.ledger import INTERRUPTED, LEDGER_FILE, Ledger, read_ledger

    grasp = CommandResult(command="grasp", ok=False, reason="no contact", sim_time=2.0)
    contacts = tuple(f"link_{k} + link_{k + 1}" for k in range(60))  # too long for a line
    long_wait = CommandResult(command="wait", ok=True, sim_time=3.0, self_contacts=contacts)
    capture = WorldCapture(objects=("jar",), stamp=4.0, qpos=bytes(8 * 180))
    monkeypatch.setenv("ROCO_RUN_DIR", str(tmp_path))
    for planted in (False, True):
        (tmp_path / LEDGER_FILE).unlink(missing_ok=True)
        before = Ledger(tmp_path / LEDGER_FILE, life="100-aaaaaa")
        for cid, name, result in (("x", "grasp", grasp), ("y", "observe", capture), ("z", "wait", long_wait)):
            before.started(cid, name, 1.0)
            before.ended(
                cid, name, result.stamp if isinstance(result, WorldCapture) else result.sim_time, "ok", result
            )
        before.started("v", "wait", 5.0)
        before.ended("v", "wait", 5.5, INTERRUPTED, CommandResult(command="wait", ok=False, reason="stopped"))
        before.started("w", "wait", 6.0)  # cut short: no end
        before.close()
        bus = MemoryBus()
        fake = CountingFake()

        class Ex(ExecutorAgent):
            def make_executor(self, fake: CountingFake = fake) -> Any:
                return fake

            if planted:

                def _answer_from_ledger(self, conv: Any, name: str) -> bool:
                    return False

        a_ta = Peer(bus, "a_ta", "ag_ex", "C5")
        agent = Ex(bus.transport())
        with running(agent):
            a_ta.send(Performative.REQUEST, FIPA_REQUEST, "x", Grasp(arm=Arm.LEFT))
            x = a_ta.next(Performative.INFORM, Performative.FAILURE, cid="x")
            if not planted:
                a_ta.send(Performative.REQUEST, FIPA_REQUEST, "y", Observe(objects=("jar",)))
                y = a_ta.next(Performative.INFORM, Performative.FAILURE, cid="y")
                a_ta.send(Performative.REQUEST, FIPA_REQUEST, "z", Wait(duration=1.0))
                z = a_ta.next(Performative.INFORM, Performative.FAILURE, cid="z")
            for cid in ("v", "w"):
                a_ta.send(Performative.REQUEST, FIPA_REQUEST, cid, Wait(duration=1.0))
                assert (
                    a_ta.next(Performative.INFORM, Performative.FAILURE, cid=cid).performative
                    == Performative.INFORM
                )
        twice, resumed = _started_twice(read_ledger(tmp_path).entries)
        if planted:  # the loop ran x again
            assert fake.ran == ["grasp", "wait", "wait"] and x.performative == Performative.INFORM
            assert twice == ["grasp (x): started at 1.000, 8.000 s"]
            continue
        assert fake.ran == ["wait", "wait"] and fake.replays == ["observe"]  # v and w only
        assert agent.counters["answered_from_ledger"] == 3
        assert x.performative == Performative.FAILURE and decode_content(x.language, x.content) == grasp
        observed = decode_content(y.language, y.content)
        assert y.performative == Performative.INFORM and isinstance(observed, Observation)
        assert observed.stamp == 4.0
        assert z.performative == Performative.INFORM and decode_content(z.language, z.content) == long_wait
        replayed = [
            (e.conversation, e.command) for e in read_ledger(tmp_path).entries if e.event == "replayed"
        ]
        assert replayed == [("x", "grasp"), ("y", "observe"), ("z", "wait")]
        assert twice == [] and resumed == [
            "wait (v): started at 5.000, 8.000 s",
            "wait (w): started at 6.000, 8.000 s",
        ]


def test_the_ledger_names_each_run_s_conversation_before_the_answer(monkeypatch: Any, tmp_path: Any) -> None:
    """ag_ex writes a start and an end line of the request's conversation-id to its ledger
    (velma/executor/ledger.py) before it answers; a loop that runs the command twice (planted)
    leaves two starts, which the judge finds (services/report/ledger.py)."""
    from services.report.ledger import _started_twice
    from services.spec.names import FIPA_REQUEST
    from shared.fipa_codec import Performative
    from shared.fipa_codec.languages.l_ex import Wait
    from tests.support.peer import Peer, running
    from velma.executor.ledger import read_ledger

    monkeypatch.setenv("ROCO_RUN_DIR", str(tmp_path))
    for twice in (False, True):
        bus = MemoryBus()
        fake = LedgerFake(twice)

        class Ex(ExecutorAgent):
            def make_executor(self, fake: LedgerFake = fake) -> Any:
                return fake

        a_ta = Peer(bus, "a_ta", "ag_ex", "C5")
        agent = Ex(bus.transport())
        with running(agent):
            cid = f"c-{twice}"
            a_ta.send(Performative.REQUEST, FIPA_REQUEST, cid, Wait(duration=0.5))
            answer = a_ta.next(Performative.INFORM, cid=cid)
            lines = [e for e in read_ledger(tmp_path).entries if e.conversation == cid]  # as answered
        assert answer.conversation_id == cid
        assert [(e.event, e.sim_time, e.outcome) for e in lines[:2]] == [
            ("start", 1.0, None),
            ("end", 1.5, "ok"),
        ]
        assert len(lines) == (4 if twice else 2)
        assert len({e.life for e in lines}) == 1
    twice_found, _ = _started_twice(read_ledger(tmp_path).entries)
    assert twice_found == ["wait (c-True): started at 1.000, 2.000 s"]


def test_a_ledger_line_that_cannot_be_written_is_counted_and_the_robot_goes_on(
    monkeypatch: Any, tmp_path: Any
) -> None:
    """Planted: the ledger's file closed under ag_ex; the command is still answered."""
    from services.spec.names import FIPA_REQUEST
    from shared.fipa_codec import Performative
    from shared.fipa_codec.languages.l_ex import Wait
    from tests.support.peer import Peer, running

    monkeypatch.setenv("ROCO_RUN_DIR", str(tmp_path))
    bus = MemoryBus()
    fake = LedgerFake()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            return fake

    a_ta = Peer(bus, "a_ta", "ag_ex", "C5")
    agent = Ex(bus.transport())
    with running(agent):
        a_ta.send(Performative.REQUEST, FIPA_REQUEST, "c-0", Wait(duration=0.5))
        a_ta.next(Performative.INFORM, cid="c-0")  # ag_ex is set up: its ledger is open
        assert agent.ledger is not None and agent.counters["ledger_errors"] == 0
        agent.ledger.close()
        a_ta.send(Performative.REQUEST, FIPA_REQUEST, "c-1", Wait(duration=0.5))
        assert a_ta.next(Performative.INFORM, cid="c-1").conversation_id == "c-1"
    assert agent.counters["ledger_errors"] == 2
