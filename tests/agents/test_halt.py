"""A stop halts the running command (FIPA SC00026 §2 cancel meta-protocol on C5; paper §3.2
safe interruption): ag_ex answers a_ta's cancel of a request with ``inform`` and the
CommandResult that says ``halted`` once the robot is at rest, with ``failure`` and the
command's own result when it could not halt it, and the runtime answers a cancel of a request
already answered with ``failure``. In the whole fleet, a stop mid-pour halts the tilt at once
(not after the atomic pour), and a_ta then puts the jar down and reports Preempted; every
conversation, the cancel's included, follows its protocol."""

from __future__ import annotations

import math
import queue
import threading
from collections import defaultdict
from typing import Any

import msgspec
import pytest

from services.agents.executor.agent import ExecutorAgent
from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from services.runtime.memory_transport import MemoryBus
from services.runtime.protocol_state import CrossingTracker
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_ex import (
    HALTED,
    Arm,
    CommandResult,
    ExecutorCommand,
    Grasp,
    MoveJoints,
    MoveTool,
    Release,
    Tilt,
    Wait,
)
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.conversation import Walk
from tests.support.fake_executor import HaltingExecutor
from tests.support.memory_fleet import MemoryFleet
from tests.support.messages import communicate
from velma.scenario import TORSO_POUR

TIMEOUT = 30.0


# ------------------------------------------------------------------ ag_ex alone, C5 by hand
class ATa:
    """a_ta's side of C5 on a MemoryBus: requests and cancels to ag_ex, and its answers."""

    def __init__(self, bus: MemoryBus) -> None:
        self.bus = bus
        self.answers: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        bus.subscribe(keys.fipa_key("C5", "ag_ex", "a_ta"), lambda _k, p: self.answers.put(decode(p)))

    def send(self, perf: Performative, cid: str, reply_with: str, term: msgspec.Struct | None = None) -> None:
        msg = communicate(perf, "a_ta", "ag_ex", "fipa-request", cid, term, reply_with=reply_with)
        self.bus.publish(keys.fipa_key("C5", "a_ta", "ag_ex"), encode(msg))

    def answer(self) -> Communicate:
        return self.answers.get(timeout=TIMEOUT)


def _content(msg: Communicate) -> Any:
    return decode_content(msg.language or "", msg.content) if msg.encoding == "msgpack" else msg.content


class Running:
    """An executor whose commands run until ``finish`` or ``cancel`` ends them; ``halts``:
    whether ``cancel`` halts (else it says it could not, as for a command that just ended)."""

    def __init__(self, halts: bool) -> None:
        self.halts = halts
        self.open: dict[int, tuple[Any, Any]] = {}
        self.submitted: queue.SimpleQueue[int] = queue.SimpleQueue()
        self._next = 0
        self._lock = threading.Lock()

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def snapshot(self) -> None:
        return None

    def submit(self, command: Any, on_done: Any) -> int:
        with self._lock:
            self._next += 1
            self.open[self._next] = (command, on_done)
        self.submitted.put(self._next)
        return self._next

    def finish(self, token: int, result: CommandResult) -> None:
        with self._lock:
            _, on_done = self.open.pop(token)
        on_done(result)

    def cancel(self, token: int) -> bool:
        if not self.halts:
            return False
        with self._lock:
            command, on_done = self.open.pop(token)
        on_done(CommandResult(command=type(command).__name__.lower(), ok=False, reason=HALTED, sim_time=2.0))
        return True


def _ag_ex(executor: Running) -> tuple[MemoryBus, ExecutorAgent, threading.Thread]:
    bus = MemoryBus()

    class Ex(ExecutorAgent):
        def make_executor(self) -> Any:
            return executor

    agent = Ex(bus.transport())
    agent.engine.bind()
    thread = threading.Thread(target=agent.engine.run, daemon=True)
    thread.start()
    return bus, agent, thread


def _follows_fipa_request(*msgs: Communicate) -> None:
    """As ``roco spec verify`` follows it (services/spec_check/conformance.py): a failed
    cancel leaves the request going on (services/runtime/protocol_state.py
    ``CrossingTracker``), and the conversation has ended."""
    tracker = CrossingTracker("fipa-request")
    for msg in msgs:
        role = "initiator" if msg.sender is not None and msg.sender.name == "a_ta" else "participant"
        tracker.step(role, msg.performative)  # raises ProtocolViolation outside fipa-request and its cancel
    assert tracker.may_be_finished


WAIT = Wait(duration=5.0)


@pytest.mark.requirement("R2.1")
def test_a_cancel_of_a_running_command_is_answered_inform_halted() -> None:
    executor = Running(halts=True)
    bus, agent, thread = _ag_ex(executor)
    try:
        a_ta = ATa(bus)
        a_ta.send(Performative.REQUEST, "c1", "req-1", WAIT)
        executor.submitted.get(timeout=TIMEOUT)
        a_ta.send(Performative.CANCEL, "c1", "can-1", WAIT)
        answer = a_ta.answer()
        assert (answer.performative, answer.in_reply_to) == (Performative.INFORM, "can-1")
        result = _content(answer)
        assert isinstance(result, CommandResult) and (result.ok, result.reason) == (False, HALTED)
        assert agent.counters["halts"] == 1
        strict = Walk("fipa-request", linked=True)  # each answering the one before: cancelled
        for perf in (Performative.REQUEST, Performative.CANCEL):
            strict.step("initiator", perf)
        assert strict.step("participant", answer.performative) == "cancelled"
        _follows_fipa_request(
            communicate(Performative.REQUEST, "a_ta", "ag_ex", "fipa-request", "c1", WAIT),
            communicate(Performative.CANCEL, "a_ta", "ag_ex", "fipa-request", "c1"),
            answer,
        )
        # the cancel ended the conversation: a second one is outside the protocol
        a_ta.send(Performative.CANCEL, "c1", "can-2")
        again = a_ta.answer()
        assert (again.performative, again.in_reply_to) == (Performative.NOT_UNDERSTOOD, "can-2")
        assert agent.counters["halts"] == 1
    finally:
        agent.engine.stop()
        thread.join(10)


def test_a_command_that_could_not_be_halted_fails_the_cancel_with_its_result() -> None:
    executor = Running(halts=False)
    bus, agent, thread = _ag_ex(executor)
    try:
        a_ta = ATa(bus)
        a_ta.send(Performative.REQUEST, "c2", "req-2", WAIT)
        token = executor.submitted.get(timeout=TIMEOUT)
        a_ta.send(Performative.CANCEL, "c2", "can-3", WAIT)
        executor.finish(token, CommandResult(command="wait", ok=True, sim_time=5.0))
        failed = a_ta.answer()  # could not cancel: the command's own result
        assert (failed.performative, failed.in_reply_to) == (Performative.FAILURE, "can-3")
        result = _content(failed)
        assert isinstance(result, CommandResult) and result.ok
        strict = Walk("fipa-request", linked=True)  # each answering the one before: cancel-failed
        for perf in (Performative.REQUEST, Performative.CANCEL):
            strict.step("initiator", perf)
        assert strict.step("participant", failed.performative) == "cancel-failed"
        _follows_fipa_request(
            communicate(Performative.REQUEST, "a_ta", "ag_ex", "fipa-request", "c2", WAIT),
            communicate(Performative.CANCEL, "a_ta", "ag_ex", "fipa-request", "c2"),
            failed,
        )
        assert agent.counters["halts"] == 0
    finally:
        agent.engine.stop()
        thread.join(10)


def test_a_cancel_of_an_answered_command_gets_failure() -> None:
    executor = Running(halts=True)
    bus, agent, thread = _ag_ex(executor)
    try:
        a_ta = ATa(bus)
        a_ta.send(Performative.REQUEST, "c3", "req-3", WAIT)
        token = executor.submitted.get(timeout=TIMEOUT)
        executor.finish(token, CommandResult(command="wait", ok=True, sim_time=5.0))
        assert a_ta.answer().performative is Performative.INFORM
        a_ta.send(Performative.CANCEL, "c3", "can-4", WAIT)
        late = a_ta.answer()
        assert (late.performative, late.in_reply_to) == (Performative.FAILURE, "can-4")
        assert b"nothing to cancel" in late.content
        assert agent.counters["halts"] == 0
    finally:
        agent.engine.stop()
        thread.join(10)


# ------------------------------------------------------------------ the fleet
def _say(fleet: MemoryFleet, text: str, request_id: str) -> None:
    fleet.bus.publish(keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=text, request_id=request_id)))


def _finals(fleet: MemoryFleet, *request_ids: str) -> dict[str, list[HumanReport]]:
    """Each request's reports up to its final one."""
    out: dict[str, list[HumanReport]] = {r: [] for r in request_ids}
    while not all(out[r] and out[r][-1].kind in FINAL_REPORTS for r in request_ids):
        report = fleet.reports.get(timeout=TIMEOUT)
        if report.request_id in out:
            out[report.request_id].append(report)
    return out


@pytest.mark.requirement("R2.1")
def test_a_stop_mid_pour_halts_the_tilt_and_puts_the_jar_down() -> None:
    executor = HaltingExecutor(hold={"Tilt"})  # the pour's tilt runs until a cancel halts it
    with MemoryFleet(executor) as fleet:
        fleet.wait_for_initial_knowledge()
        _say(fleet, "pour the jar into the bowl", "pour")
        tilt = executor.running.get(timeout=TIMEOUT)
        assert isinstance(tilt, Tilt)
        _say(fleet, "stop", "stop")
        reports = _finals(fleet, "pour", "stop")
        published = list(fleet.bus.published)
        commands = list(executor.commands)
    assert reports["pour"][-1].kind is ReportKind.STOPPED, reports["pour"]
    assert reports["stop"][-1].kind is ReportKind.STOPPED, reports["stop"]
    # ag_ex halted the tilt itself, mid-pour: the atomic pour was not run to its end
    assert executor.cancelled == [tilt]
    after = commands[commands.index(tilt) + 1 :]
    assert not any(isinstance(c, Tilt | Wait) for c in after), after  # no wait, no tilt back
    # then a_ta's safe stop put the jar down: carried to the table and released by its hand
    releases = [i for i, c in enumerate(after) if isinstance(c, Release) and c.arm == tilt.arm]
    assert releases and any(isinstance(c, MoveTool) and c.arm == tilt.arm for c in after[: releases[0]])
    assert all(c.arm != Arm.RIGHT for c in after if isinstance(c, Release))  # no other hand opened
    msgs = [decode(p) for k, p in published if k.startswith("roco/fipa/")]
    # C5: a_ta's cancel, answered inform with the halted result
    c5 = [
        m
        for m in msgs
        if m.conversation_id
        and any(
            n.performative is Performative.CANCEL
            for n in msgs
            if n.conversation_id == m.conversation_id and n.sender and n.sender.name == "a_ta"
        )
    ]
    cancel = next(m for m in c5 if m.performative is Performative.CANCEL)
    answer = next(m for m in c5 if m.in_reply_to == cancel.reply_with)
    assert answer.performative is Performative.INFORM
    assert _content(answer).reason == HALTED
    # C1: Terminating, then Preempted, saying what was halted and where the jar went
    states = [
        _content(m)
        for m in msgs
        if m.sender
        and m.sender.name == "a_ta"
        and m.performative is Performative.INFORM
        and m.protocol == "coordinate"
    ]
    sw = [s for s in states if isinstance(s, SWStatus)]
    kinds = [s.state for s in sw]
    assert SWState.TERMINATING in kinds and kinds[-1] is SWState.PREEMPTED, kinds
    assert "halted" in (sw[-1].reason or "") and "tilt" in (sw[-1].reason or "")
    assert "put the jar down on the table" in (sw[-1].reason or ""), sw[-1].reason
    # every conversation, the cancel's included, follows its protocol
    conversations: dict[str, list[Communicate]] = defaultdict(list)
    for m in msgs:
        conversations[m.conversation_id or ""].append(m)
    for cid, conv in conversations.items():
        tracker = Walk(conv[0].protocol or "")
        for m in conv:
            tracker.observe(m)
        if conv[0].protocol not in ("fipa-subscribe",):
            # a cancel that failed ends the conversation in FIPA's machine, and may leave it
            # going on by the runtime's rules (services/runtime/protocol_state.py)
            assert tracker.is_finished or tracker.state == "cancel-failed", (
                cid,
                [m.performative.value for m in conv],
            )


def _turning_to_pour(command: ExecutorCommand) -> bool:
    return isinstance(command, MoveJoints) and math.isclose(
        command.positions.get("torso_0_joint", 0.0), TORSO_POUR, abs_tol=1e-6
    )


@pytest.mark.parametrize("moment", ["Grasp", "MoveJoints", "turn to pour"])
def test_a_stop_in_a_take_or_a_turn_is_halted_and_ends_preempted(moment: str) -> None:
    """The first grasp (a take: halted, then finished, and the jar put down), the first torso
    turn (nothing in hand: the robot stays where it halted) and the turn to pour with the jar
    in hand (the torso turned so that the safe stop runs as planned, then the jar put down)."""
    if moment == "turn to pour":
        executor = HaltingExecutor(hold={"MoveJoints"}, when=_turning_to_pour)
    else:
        executor = HaltingExecutor(hold={moment})
    with MemoryFleet(executor) as fleet:
        fleet.wait_for_initial_knowledge()
        _say(fleet, "pour the jar into the bowl", "pour")
        held = executor.running.get(timeout=TIMEOUT)
        _say(fleet, "stop", "stop")
        reports = _finals(fleet, "pour", "stop")
        published = list(fleet.bus.published)
        commands = list(executor.commands)
    assert reports["pour"][-1].kind is ReportKind.STOPPED, reports["pour"]
    assert executor.cancelled == [held]
    msgs = [decode(p) for k, p in published if k.startswith("roco/fipa/")]
    final = [
        _content(m)
        for m in msgs
        if m.sender
        and m.sender.name == "a_ta"
        and m.protocol == "coordinate"
        and m.performative is Performative.INFORM
    ][-1]
    assert isinstance(final, SWStatus) and final.state is SWState.PREEMPTED
    assert "halted" in (final.reason or "")
    after = commands[commands.index(held) + 1 :]
    if moment == "Grasp":  # the take's rest ran: the grasp again, then the lift and the withdrawal
        grasps = [c for c in commands if isinstance(c, Grasp)]
        assert len(grasps) == 2 and grasps[0] is held, grasps
        assert "put the jar down on the table" in (final.reason or ""), final.reason
    elif moment == "MoveJoints":  # nothing in hand: no safe stop, nothing more moves
        assert "nothing was held" in (final.reason or "") and not after, after
    else:  # the torso turned (back, or on) before the safe stop carried the jar to the table
        assert isinstance(after[0], MoveJoints) and "torso_0_joint" in after[0].positions, after[:2]
        assert any(isinstance(c, Release) and c.arm == Arm.LEFT for c in after), after
        assert "put the jar down on the table" in (final.reason or ""), final.reason
