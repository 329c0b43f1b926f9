"""A robot primitive added in one table per layer (docs/executor.md, "Adding a robot
primitive"), run through a_pl, a_ta and ag_ex.

The test adds ``Hold(duration)`` — the robot keeps its setpoints for ``duration`` s — as an
L_EX command (``add_command``), a velma primitive (``PRIMITIVES``), a planner action
(``ACTIONS``) with its HFSM leaf (``LEAVES``) and an expected duration (``EXPECTED_S``), and
the specification's C5 request may carry it. Every row is taken back after the test.

a_pl's part runs in process: GTPyhop plans a task whose method uses the action, and
``to_hfsm`` makes the plan a_ta runs. a_ta and ag_ex run as agents (their FSMs in threads) on
a MemoryBus, ag_ex on the real executor (velma/executor/core.py: the control loop and the
MuJoCo kitchen in a thread, perception by ground truth); the test speaks for a_co."""

from __future__ import annotations

import contextlib
import io
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.agents.executor.agent import ExecutorAgent
from services.agents.planner import domain
from services.agents.planner.hfsm import LEAVES, Leaf, to_hfsm
from services.agents.task_executor.agent import TaskExecutor
from services.agents.task_executor.expected import EXPECTED_S, UNTIMED_S, expected_s
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.spec.model import DEFAULT_SPEC, SystemSpec, load
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages import base, decode_content
from shared.fipa_codec.languages.l_ex import COMMANDS, CommandResult, add_command
from shared.fipa_codec.languages.l_hfsm import Execute, HierarchicalPlan
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from tests.support.messages import communicate
from velma.executor.core import Executor
from velma.executor.primitives import PRIMITIVES
from velma.executor.runtime import Runtime

with contextlib.redirect_stdout(io.StringIO()):
    import gtpyhop

TIMEOUT_S = 30.0
HOLD_S = 0.2


class Hold(msgspec.Struct, frozen=True, tag="hold", kw_only=True):
    """Keep the current setpoints for ``duration`` s."""

    duration: float


class HoldPrimitive:
    """Hold's primitive: ends ``ok`` once ``duration`` s of robot time have passed."""

    def __init__(self, command: Hold) -> None:
        self.command = command
        self.end = 0.0

    def start(self, rt: Runtime) -> CommandResult | None:
        self.end = rt.time + self.command.duration
        return None

    def step(self, rt: Runtime) -> CommandResult | None:
        return CommandResult(command="hold", ok=True, sim_time=rt.time) if rt.time >= self.end else None


def a_hold(s: Any, path: str, duration: float) -> Any:
    """The planner action: the state, one step on."""
    s.steps += 1
    return s


def hold_leaf(duration: float) -> Leaf:
    return Execute(Hold(duration=duration)), duration  # type: ignore[arg-type]  # added at run time


def m_hold_still(s: Any, path: str, duration: float) -> list[tuple[Any, ...]]:
    """A task method that uses the action."""
    return [("a_hold", f"{path}/hold", duration)]


def with_hold(spec_text: str) -> str:
    """The specification's text with Hold among the contents of a_ta's requests on C5."""
    listed = '"Observe", "Wait"]'
    assert spec_text.count(listed) == 1
    return spec_text.replace(listed, '"Observe", "Wait", "Hold"]')


@pytest.fixture
def hold(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[SystemSpec]:
    """Hold in every table (taken back afterwards); the specification that lets a_ta send it."""
    l_ex = base.LANGUAGES["L_EX"]
    monkeypatch.setitem(base.LANGUAGES, "L_EX", l_ex)
    for t in l_ex.types:
        monkeypatch.setitem(base._BY_TYPE, t, l_ex)
    monkeypatch.setitem(COMMANDS, "hold", Hold)
    add_command(Hold)
    monkeypatch.setitem(PRIMITIVES, Hold, HoldPrimitive)
    monkeypatch.setitem(domain.ACTIONS, "a_hold", a_hold)
    monkeypatch.setitem(LEAVES, "a_hold", hold_leaf)
    monkeypatch.setitem(EXPECTED_S, Hold, lambda c: c.duration)
    domain.declare()
    gtpyhop_domain = gtpyhop.find_domain_by_name(domain.DOMAIN_NAME)
    monkeypatch.setitem(gtpyhop_domain._action_dict, "a_hold", a_hold)
    monkeypatch.setitem(gtpyhop_domain._task_method_dict, "hold_still", [m_hold_still])
    spec = tmp_path / "spec.toml"
    spec.write_text(with_hold(DEFAULT_SPEC.read_text()))
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    yield load(spec)
    del base._BY_TYPE[Hold]


def plan_hold() -> HierarchicalPlan:
    """a_pl's part: GTPyhop's plan for ``hold_still``, as the HFSM a_ta runs."""
    domain.declare()
    state = gtpyhop.State("test")
    state.steps = 0
    with contextlib.redirect_stdout(io.StringIO()):
        actions = gtpyhop.find_plan(state, [("hold_still", "hold_still", HOLD_S)])
    assert actions == [("a_hold", "hold_still/hold", HOLD_S)]
    root, complete, cost = to_hfsm(actions)
    assert complete and cost == HOLD_S
    return HierarchicalPlan(plan_id="cmd-1-p1", task_id="cmd-1", root=root, complete=True, cost=cost)


def content(msg: Communicate) -> object:
    return decode_content(msg.language, msg.content) if msg.language and msg.content else None


def run_plan(spec: SystemSpec, plan: HierarchicalPlan) -> tuple[SWStatus, list[Communicate]]:
    """a_ta and ag_ex (on the real executor) run ``plan``, a_co's request; the final state
    a_ta reports, and every communicate."""
    bus = MemoryBus()
    a_co = bus.transport()
    seen: list[Communicate] = []
    final: list[SWStatus] = []
    ended = threading.Event()

    def collect(_key: str, payload: bytes) -> None:
        """Keep every communicate; as a_co, confirm each of a_ta's reports (L_SW)."""
        msg = decode(payload)
        seen.append(msg)
        said = content(msg)
        if isinstance(said, SWStatus):
            confirm = communicate(
                Performative.CONFIRM,
                "a_co",
                "a_ta",
                "coordinate",
                msg.conversation_id,
                in_reply_to=msg.reply_with,
            )
            a_co.publish(keys.fipa_key("C1", "a_co", "a_ta"), encode(confirm))
            if said.state in TERMINAL_SW_STATES:
                final.append(said)
                ended.set()

    bus.subscribe(keys.FIPA_ALL, collect)
    executor = Executor(realtime=False, seed=0, perception="truth")

    class AgEx(ExecutorAgent):
        def make_executor(self) -> Any:
            return executor

    agents = [TaskExecutor(bus.transport(), spec), AgEx(bus.transport(), spec)]
    a_co.announce(keys.alive_key("a_co"))
    for agent in agents:
        agent.bind()
    threads = [threading.Thread(target=a.run, name=a.name, daemon=True) for a in agents]
    for thread in threads:
        thread.start()
    try:
        request = communicate(
            Performative.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec1", plan, reply_with="p1"
        )
        a_co.publish(keys.fipa_key("C1", "a_co", "a_ta"), encode(request))
        assert ended.wait(TIMEOUT_S), "\n".join(f"{m.performative.value} {content(m)}" for m in seen)
    finally:
        for agent in agents:
            agent.stop()
        for thread in threads:
            thread.join(10)
        executor.stop()
    return final[0], seen


def from_ag_ex(seen: list[Communicate]) -> list[tuple[str, object]]:
    """ag_ex's answers: (performative, content)."""
    return [
        (m.performative.value, content(m)) for m in seen if m.sender is not None and m.sender.name == "ag_ex"
    ]


def test_a_new_primitive_runs_through_a_pl_a_ta_and_ag_ex(hold: SystemSpec) -> None:
    plan = plan_hold()
    assert plan.root.children[0].action == Execute(Hold(duration=HOLD_S))  # type: ignore[arg-type]
    assert expected_s(Hold(duration=HOLD_S)) == HOLD_S
    final, seen = run_plan(hold, plan)
    assert final.state is SWState.SUCCEEDED, final
    assert Hold(duration=HOLD_S) in [content(m) for m in seen if m.receiver[0].name == "ag_ex"]
    (result,) = [c for p, c in from_ag_ex(seen) if isinstance(c, CommandResult)]
    assert result.command == "hold" and result.ok, result


def test_without_its_executor_row_ag_ex_fails_it(hold: SystemSpec, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(PRIMITIVES, Hold)
    final, seen = run_plan(hold, plan_hold())
    assert final.state is not SWState.SUCCEEDED
    (result,) = [c for p, c in from_ag_ex(seen) if isinstance(c, CommandResult)]
    assert not result.ok and "not an executor command: Hold" in (result.reason or ""), result


def test_without_its_l_ex_row_ag_ex_refuses_it(hold: SystemSpec, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(COMMANDS, "hold")
    final, seen = run_plan(hold, plan_hold())
    assert final.state is not SWState.SUCCEEDED
    answers = from_ag_ex(seen)
    assert "refuse" in [p for p, _ in answers] and not [c for _, c in answers if isinstance(c, CommandResult)]


def test_without_its_rows_a_pl_has_no_plan_and_no_leaf(
    hold: SystemSpec, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(LEAVES, "a_hold")
    with pytest.raises(ValueError, match="unknown planner action a_hold"):
        plan_hold()
    monkeypatch.delitem(gtpyhop.find_domain_by_name(domain.DOMAIN_NAME)._action_dict, "a_hold")
    state = gtpyhop.State("test")
    state.steps = 0
    with contextlib.redirect_stdout(io.StringIO()), pytest.raises(Exception, match="Nothing named 'a_hold'"):
        gtpyhop.find_plan(state, [("hold_still", "hold_still", HOLD_S)])


def test_without_its_duration_row_a_ta_expects_the_default(
    hold: SystemSpec, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(EXPECTED_S, Hold)
    assert expected_s(Hold(duration=HOLD_S)) == UNTIMED_S
