"""Issue-4 scenarios on the agents themselves (MemoryBus, kinematic robot double): several
commands, an urgent command preempting a pour (cancel → Terminating → safe stop →
Preempted → resumed), a person's stop, an object moved behind the robot's back (Replan), an
impossible command, and "what are you doing". The physics versions run in
tests/integration/test_scenarios.py."""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import msgspec
import pytest

from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from shared.fipa_codec import Performative, decode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    NOT_AT_GRASP_POSE,
    CommandResult,
    ExecutorCommand,
    Grasp,
    MoveJoints,
)
from shared.fipa_codec.languages.l_hfsm import Assert
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
from tests.support.fake_executor import PARTICLES, FakeExecutor
from tests.support.memory_fleet import MemoryFleet

TIMEOUT = 30.0
TORSO_POUR = -1.2


def turning_to_pour(command: ExecutorCommand) -> bool:
    return isinstance(command, MoveJoints) and math.isclose(
        command.positions.get("torso_0_joint", 0.0), TORSO_POUR, abs_tol=1e-6
    )


class GatedExecutor(FakeExecutor):
    """The kinematic double, holding back the first command ``gate`` matches until
    :meth:`release`: the robot is busy with it for as long as the test needs."""

    def __init__(self, gate: Callable[[ExecutorCommand], bool], **kw: Any) -> None:
        super().__init__(**kw)
        self.gate = gate
        self.gated = threading.Event()
        self._pending: tuple[ExecutorCommand, Callable[[CommandResult | Observation], None]] | None = None

    def submit(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> None:
        if not self.gated.is_set() and self.gate(command):
            self._pending = (command, on_done)
            self.gated.set()
            return
        super().submit(command, on_done)

    def release(self) -> None:
        assert self._pending is not None
        command, on_done = self._pending
        super().submit(command, on_done)


class Session(MemoryFleet):
    """A MemoryFleet a test talks to like a person: say, wait for outcomes and traffic."""

    def __init__(self, executor: Any | None = None) -> None:
        super().__init__(executor)
        self.by_request: dict[str, list[HumanReport]] = {}
        self.ended: dict[str, threading.Event] = {}
        self.lock = threading.Lock()
        self.bus.subscribe(keys.HUMAN_OUT, self._report)

    def _report(self, _key: str, payload: bytes) -> None:
        report = msgspec.json.decode(payload, type=HumanReport)
        with self.lock:
            self.by_request.setdefault(report.request_id, []).append(report)
            if report.kind in FINAL_REPORTS:
                self.ended.setdefault(report.request_id, threading.Event()).set()

    def say(self, text: str, request_id: str, priority: int = 0) -> None:
        with self.lock:
            self.ended.setdefault(request_id, threading.Event())
        payload = HumanInput(text=text, request_id=request_id, priority=priority)
        self.bus.publish(keys.HUMAN_IN, msgspec.json.encode(payload))

    def final(self, request_id: str, timeout: float = TIMEOUT) -> HumanReport:
        assert self.ended[request_id].wait(timeout), (
            f"{request_id}: no outcome; {self.by_request.get(request_id)}"
        )
        return next(r for r in self.by_request[request_id] if r.kind in FINAL_REPORTS)

    def traffic(self) -> list[tuple[str, Any, Any]]:
        out = []
        for key, payload in list(self.bus.published):
            if key.startswith("roco/fipa/"):
                msg = decode(payload)
                content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
                out.append((key, msg, content))
        return out

    def wait_for(self, predicate: Callable[[str, Any, Any], bool], timeout: float = TIMEOUT) -> None:
        """Block until a communicate satisfying ``predicate`` was published."""
        seen = threading.Event()

        def check(key: str, payload: bytes) -> None:
            if key.startswith("roco/fipa/"):
                msg = decode(payload)
                content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
                if predicate(key, msg, content):
                    seen.set()

        self.bus.subscribe("roco/fipa/**", check)
        if any(predicate(*t) for t in self.traffic()):
            return
        assert seen.wait(timeout), "the awaited communicate never came"

    def sw_states(self) -> list[SWStatus]:
        return [c for k, m, c in self.traffic() if isinstance(c, SWStatus) and m.sender.name == "a_ta"]


def is_cancel_to_ta(key: str, msg: Any, content: Any) -> bool:
    return key == keys.fipa_key("C1", "a_co", "a_ta") and msg.performative is Performative.CANCEL


def interrupt_pour(s: Session, robot: GatedExecutor, sentence: str, request_id: str) -> None:
    """Start the pour, and say ``sentence`` while the robot turns to pour (the jar in hand)."""
    s.wait_for_initial_knowledge()
    s.say("pour the jar into the bowl", "pour")
    assert robot.gated.wait(TIMEOUT), "the pour never turned to pour"
    s.say(sentence, request_id)


@pytest.mark.requirement("R1.2")
def test_two_commands_in_a_row() -> None:
    with Session() as s:
        s.wait_for_initial_knowledge()
        s.say("bring the cup to the table", "r1")
        assert s.final("r1").kind is ReportKind.SUCCEEDED
        s.say("pour the jar into the bowl", "r2")
        assert s.final("r2").kind is ReportKind.SUCCEEDED
    assert s.executor.inside["bowl"] == PARTICLES
    cup, bowl = s.executor.poses["cup"].position, s.executor.poses["bowl"].position
    assert math.dist(cup[:2], bowl[:2]) >= 0.12  # the bowl went to a free place


@pytest.mark.requirement("R1.2", "R2.1")
def test_an_urgent_command_preempts_the_pour_which_resumes_and_finishes() -> None:
    robot = GatedExecutor(turning_to_pour)
    with Session(robot) as s:
        interrupt_pour(s, robot, "urgently bring the cup to the table", "cup")
        s.wait_for(is_cancel_to_ta)
        robot.release()
        assert s.final("cup").kind is ReportKind.SUCCEEDED
        assert s.final("pour").kind is ReportKind.SUCCEEDED
        traffic = s.traffic()
    states = [c.state for k, m, c in traffic if isinstance(c, SWStatus) and m.sender.name == "a_ta"]
    i = states.index(SWState.TERMINATING)
    assert SWState.PREEMPTED in states[i:], states
    # the jar was put down on the table by the safe stop before Preempted, never dropped
    asserts = [c for k, m, c in traffic if isinstance(c, WorldUpdate) and c.stamp == -1.0]
    changes = [o for u in asserts for o in u.objects]
    assert ObjectUpdate(name="jar", location="table", relation="on", held_by="") in changes
    assert robot.inside["bowl"] == PARTICLES and robot.inside["jar"] == 0
    progress = [r for r in s.by_request["pour"] if r.kind is ReportKind.PROGRESS]
    assert any("preempted" in r.text.lower() for r in progress)


def test_a_command_that_ends_as_a_ta_cancels_it_counts_as_done() -> None:
    """The turn to pour ends (ag_ex informs a_ta, and forgets the request) while a_ta's cancel
    of it is on the wire: ag_ex answers that cancel ``failure`` (nothing to cancel), after the
    result. The leaf is done; the preempted pour resumes and finishes."""
    robot = GatedExecutor(turning_to_pour)
    s = Session(robot)
    to_ex, from_ex = keys.fipa_key("C5", "a_ta", "ag_ex"), keys.fipa_key("C5", "ag_ex", "a_ta")
    result_sent, cancel_answered = threading.Event(), threading.Event()

    def answer(_key: str, payload: bytes) -> None:
        perf = decode(payload).performative
        if perf is Performative.INFORM and robot.gated.is_set():
            result_sent.set()
        elif perf is Performative.FAILURE and result_sent.is_set():
            cancel_answered.set()

    def cancel_on_the_wire(_key: str, payload: bytes) -> None:
        # subscribed before the agents: runs (in a_ta's thread) before ag_ex receives the cancel
        if decode(payload).performative is Performative.CANCEL and not result_sent.is_set():
            robot.release()
            assert result_sent.wait(TIMEOUT), "ag_ex never sent the turn's result"

    def cancel_delivered(_key: str, payload: bytes) -> None:
        # subscribed after the agents: a_ta reads on only when both answers wait for it
        if decode(payload).performative is Performative.CANCEL and result_sent.is_set():
            assert cancel_answered.wait(TIMEOUT), "ag_ex never answered the cancel"

    s.bus.subscribe(from_ex, answer)
    s.bus.subscribe(to_ex, cancel_on_the_wire)
    with s:
        s.bus.subscribe(to_ex, cancel_delivered)
        interrupt_pour(s, robot, "urgently bring the cup to the table", "cup")
        assert s.final("cup").kind is ReportKind.SUCCEEDED
        assert s.final("pour").kind is ReportKind.SUCCEEDED, s.by_request["pour"]
        answers = [m for k, m, _ in s.traffic() if k == from_ex and m.performative is Performative.FAILURE]
    assert any("nothing to cancel" in str(m.content) for m in answers)


OnDone = Callable[[CommandResult | Observation], None]


class Surprising(FakeExecutor):
    """The kinematic double that, the first time ``when`` matches a command, calls
    ``surprise(double, on_done)`` first; it answers the command itself when that returns True."""

    def __init__(
        self, when: Callable[[ExecutorCommand], bool], surprise: Callable[[FakeExecutor, OnDone], bool]
    ) -> None:
        super().__init__()
        self.when, self.surprise, self.surprised = when, surprise, False

    def submit(self, command: ExecutorCommand, on_done: OnDone) -> object:
        if not self.surprised and self.when(command):
            self.surprised = True
            if self.surprise(self, on_done):
                return object()
        return super().submit(command, on_done)


def goes_back(robot: FakeExecutor, _on_done: OnDone) -> bool:
    """The answer comes from an older world (simulated time went backwards)."""
    robot.t = 0.5
    return False


def hand_elsewhere(robot: FakeExecutor, on_done: OnDone) -> bool:
    """The grasp finds the hand 52 mm from its grasp pose."""
    robot.t += 1.0
    on_done(
        CommandResult(command="grasp", ok=False, reason=NOT_AT_GRASP_POSE, sim_time=robot.t, tool_error=0.052)
    )
    return True


def test_an_answer_from_a_world_gone_back_in_time_makes_a_ta_look_and_replan() -> None:
    with Session(Surprising(turning_to_pour, goes_back)) as s:
        s.wait_for_initial_knowledge()
        s.say("pour the jar into the bowl", "pour")
        assert s.final("pour").kind is ReportKind.SUCCEEDED
        replans = [c.reason or "" for c in s.sw_states() if c.state is SWState.REPLAN]
    back = [r for r in replans if "went back" in r]
    assert len(back) == 1, replans
    assert "face_pour: ag_ex's world went back from" in back[0] and "to 1.50 s" in back[0]


def test_a_grasp_away_from_its_grasp_pose_makes_a_ta_look_and_replan() -> None:
    with Session(Surprising(lambda command: isinstance(command, Grasp), hand_elsewhere)) as s:
        s.wait_for_initial_knowledge()
        s.say("pour the jar into the bowl", "pour")
        assert s.final("pour").kind is ReportKind.SUCCEEDED
        replans = [c.reason or "" for c in s.sw_states() if c.state is SWState.REPLAN]
        errors = [c for c in s.sw_states() if c.state is SWState.ERROR]
    assert any("take/grasp: the hand was not at the grasp pose" in r for r in replans), replans
    assert not errors


def test_a_stop_puts_the_held_jar_down_safely() -> None:
    robot = GatedExecutor(turning_to_pour)
    with Session(robot) as s:
        interrupt_pour(s, robot, "stop", "halt")
        s.wait_for(is_cancel_to_ta)
        robot.release()
        assert s.final("pour").kind is ReportKind.STOPPED
        s.final("halt")
    assert robot.held == {"left": None, "right": None}
    assert robot.poses["jar"].position[2] > 0.7  # standing on the table, not on the floor
    assert robot.inside["jar"] == PARTICLES  # not poured


@pytest.mark.requirement("R2.1", "R3.2")
def test_an_object_moved_behind_the_robots_back_makes_it_replan() -> None:
    with Session() as s:
        s.wait_for_initial_knowledge()
        x, y, z = s.executor.poses["jar"].position
        s.executor.poses["jar"] = Pose((x, y - 0.06, z))
        s.say("pour the jar into the bowl", "r1")
        assert s.final("r1").kind is ReportKind.SUCCEEDED
        replans = [c for c in s.sw_states() if c.state is SWState.REPLAN and "expects" in (c.reason or "")]
    assert replans and "jar is 6 cm from where the plan expects it" in (replans[0].reason or "")


def test_an_impossible_command_is_refused_with_a_reason() -> None:
    with Session() as s:
        s.wait_for_initial_knowledge()
        s.say("pour the jar into the cabinet", "r1")
        s.say("bring the table to the table", "r2")
        first, second = s.final("r1"), s.final("r2")
    assert first.kind is ReportKind.FAILED and "how to pour the jar into the cabinet" in first.text
    assert second.kind is ReportKind.FAILED and "cannot pick up the table" in second.text


def test_what_are_you_doing_names_the_running_command() -> None:
    robot = GatedExecutor(turning_to_pour)
    with Session(robot) as s:
        interrupt_pour(s, robot, "what are you doing?", "q")
        status = s.final("q")
        robot.release()
        s.final("pour")
    assert status.kind is ReportKind.STATUS
    assert "pour the jar into the bowl" in status.text and "running" in status.text


def test_safe_stops_are_planned_only_where_something_is_held() -> None:
    with Session() as s:
        s.wait_for_initial_knowledge()
        s.say("pour the jar into the bowl", "r1")
        s.final("r1")
        traffic = s.traffic()
    from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan

    plans = [c for k, m, c in traffic if isinstance(c, HierarchicalPlan) and m.sender.name == "a_pl"]
    first = plans[0]
    leaves = first.root.leaves()
    held_at = next(
        i for i, (p, n) in enumerate(leaves) if isinstance(n.action, Assert) and n.action.relation == "heldBy"
    )
    assert all(n.on_cancel is None for _, n in leaves[:held_at])
    assert any(n.on_cancel is not None for _, n in leaves[held_at + 1 :])
    for stop in first.safe_stops.values():
        assert any(isinstance(n.action, Assert) and n.action.relation == "on" for _, n in stop.leaves())
    # each plan says how many queries and how long it took (how long: scripts/bench_planning.py)
    assert all(p.km_queries > 0 and p.planning_time_s is not None and p.planning_time_s > 0 for p in plans)


@pytest.mark.requirement("R2.1")
def test_the_report_of_a_preemption_shows_cancel_terminating_preempted(tmp_path: Any) -> None:
    from services.recorder.recorder import TrafficWriter
    from services.report import build_report
    from services.report.markdown import render

    robot = GatedExecutor(turning_to_pour)
    with Session(robot) as s:
        interrupt_pour(s, robot, "urgently bring the cup to the table", "cup")
        s.wait_for(is_cancel_to_ta)
        robot.release()
        s.final("cup")
        s.final("pour")
        published = list(s.bus.published)
    writer = TrafficWriter(tmp_path)
    for i, (key, payload) in enumerate(published):
        if key.startswith("roco/fipa/"):
            writer.write(1000.0 + 0.01 * i, key, payload)
    writer.close()
    report = build_report(tmp_path)
    assert [(c.text, c.outcome) for c in report.commands] == [
        ("pour the jar into the bowl", "succeeded"),
        ("urgently bring the cup to the table", "succeeded"),
    ]
    texts = [e.text for e in report.coordination]
    cancel = next(i for i, t in enumerate(texts) if t.startswith("cancel"))
    terminating = next(i for i, t in enumerate(texts) if t.startswith("Terminating"))
    preempted = next(i for i, t in enumerate(texts) if t.startswith("Preempted"))
    assert cancel < terminating < preempted
    assert "put the jar down on the table" in texts[preempted]
    md = render(report)
    assert "## 7. Commands and coordination" in md and "Preempted" in md


def test_every_conversation_of_a_preemption_and_a_stop_follows_its_protocol() -> None:
    from collections import defaultdict

    from shared.fipa_codec import Communicate
    from tests.support.conversation import Walk

    robot = GatedExecutor(turning_to_pour)
    with Session(robot) as s:
        interrupt_pour(s, robot, "urgently bring the cup to the table", "cup")
        s.wait_for(is_cancel_to_ta)
        s.say("what are you doing", "q")
        s.final("q")
        robot.release()
        s.final("cup")
        s.final("pour")
        s.say("put the cup back in the cabinet", "back")
        s.say("stop", "halt")
        s.final("halt")
        s.final("back")
        published = list(s.bus.published)
    conversations: dict[str, list[Communicate]] = defaultdict(list)
    for key, payload in published:
        if key.startswith("roco/fipa/"):
            msg = decode(payload)
            conversations[msg.conversation_id or ""].append(msg)
    seen = set()
    for cid, msgs in conversations.items():
        tracker = Walk(msgs[0].protocol or "")
        for msg in msgs:
            tracker.observe(msg)  # raises ProtocolViolation on a step outside the protocol
        seen.add((msgs[0].protocol, msgs[0].performative.value))
        if msgs[0].protocol != "fipa-subscribe":
            # a cancel that failed (the command ran to its end: its result in the failure) ends
            # the conversation in FIPA's machine, and may leave it going on by the runtime's
            # rules (services/runtime/protocol_state.py): the first reading is FIPA's
            assert tracker.is_finished or tracker.state == "cancel-failed", (
                cid,
                [m.performative.value for m in msgs],
            )
    assert ("coordinate", "request") in seen and ("fipa-query", "query-ref") in seen
    cancels = [m for ms in conversations.values() for m in ms if m.performative is Performative.CANCEL]
    assert {m.protocol for m in cancels} >= {"coordinate"}


class FailsOnceExecutor(FakeExecutor):
    """The kinematic double whose first command of type ``kind`` fails with ``reason`` (as ag_ex
    reports it, ``CommandResult.command`` ``name``); every other command runs as usual."""

    def __init__(self, kind: type, name: str, reason: str) -> None:
        super().__init__()
        self.kind, self.name, self.reason = kind, name, reason
        self.failed = False

    def submit(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> None:
        if isinstance(command, self.kind) and not self.failed:
            self.failed = True
            self.commands.append(command)
            on_done(CommandResult(command=self.name, ok=False, reason=self.reason, sim_time=self.t))
            return
        super().submit(command, on_done)


def test_a_grasp_that_closes_on_nothing_makes_a_ta_look_and_replan() -> None:
    from shared.fipa_codec.languages.l_ex import Grasp

    robot = FailsOnceExecutor(Grasp, "grasp", "no contact")  # the object was not there
    with Session(robot) as s:
        s.wait_for_initial_knowledge()
        s.say("bring the cup to the table", "r1")
        assert s.final("r1").kind is ReportKind.SUCCEEDED
        states = s.sw_states()
        traffic = s.traffic()
    replans = [c for c in states if c.state is SWState.REPLAN]
    assert replans and "the grasp closed on nothing" in (replans[0].reason or "")
    # a_ta looked at the whole scene before reporting Replan, and told a_km what it saw
    replan_at = next(i for i, (k, m, c) in enumerate(traffic) if c is replans[0] or c == replans[0])
    seen = [c for k, m, c in traffic[:replan_at] if isinstance(c, WorldUpdate) and len(c.objects) >= 4]
    assert len(seen) >= 2  # the initial observation and the one after the failed grasp


def test_a_pose_no_arm_reaches_makes_a_ta_look_and_replan() -> None:
    from shared.fipa_codec.languages.l_ex import MoveTool

    # a pose planned from an object seen in the wrong place
    robot = FailsOnceExecutor(MoveTool, "move_tool", "unreachable")
    with Session(robot) as s:
        s.wait_for_initial_knowledge()
        s.say("bring the cup to the table", "r1")
        assert s.final("r1").kind is ReportKind.SUCCEEDED
        states = s.sw_states()
    replans = [c for c in states if c.state is SWState.REPLAN]
    assert robot.failed
    assert any("no arm configuration reaches the planned pose" in (c.reason or "") for c in replans)
