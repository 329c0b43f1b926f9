"""A robot primitive added in one table per layer (docs/executor.md, "Adding a robot
primitive"), run through a_pl, and through a_ta and ag_ex in a fleet.

The test adds ``Hold(duration)`` — the robot keeps its setpoints for ``duration`` s;
tests/support/hold.py — as an L_EX command (``add_command``), a velma primitive
(``PRIMITIVES``), a planner action (``ACTIONS``) with its HFSM leaf (``LEAVES``) and an expected
duration (``EXPECTED_S``), and the specification's C5 request may carry it. In this process
every row is taken back after the test.

a_pl's part runs in this process: GTPyhop plans a task whose method uses the action, and
``to_hfsm`` makes the plan a_ta runs. a_ta and ag_ex run as a fleet: a Zenoh router on a free
loopback port (explicit endpoint, no multicast), the traffic recorder, and the two agents, each
a process of its own started by the launcher (services/fleet/launcher.py: a fresh interpreter,
spawn semantics) through the test's entry module tests/support/hold_agent.py, which registers
Hold's rows in the process before the agent's main runs, with the specification that lists Hold
(``ROCO_SPEC``). ag_ex runs its real control loop in a process of its own
(velma/executor/process.py ``ExecutorProcess``, which imports the entry module again, rows and
all), the kitchen's physics in that loop (``ROCO_WORLD=loop``), perception by the physics'
ground truth (``ROCO_PERCEPTION=truth``: Hold observes nothing). Every communicate goes through
the router (``ROCO_LINKS=router``): the router passes ag_ex's answer on to a_co before a_ta's
report that follows from it, so what the test heard is complete once the plan has ended (with
direct links between the agents, ag_ex's answer may reach the test after a_ta's report).

The test speaks for a_co over Zenoh: it sends the plan, confirms each of a_ta's reports, and
keeps every communicate it hears; after the run, ag_ex's ledger and the recorded traffic
(``roco spec verify``'s check, against the specification that lists Hold and against the
shipped one) are read from the run folder. A fleet run takes about 2–5 s of wall time."""

from __future__ import annotations

import contextlib
import io
import threading
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

from services.agents.planner import domain
from services.agents.planner.hfsm import LEAVES, to_hfsm
from services.agents.task_executor.expected import EXPECTED_S, UNTIMED_S, expected_s
from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.transport import ZenohTransport
from services.spec.model import DEFAULT_SPEC
from services.spec_check.conformance import verify_report
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import base, decode_content
from shared.fipa_codec.languages.l_ex import COMMANDS, CommandResult, add_command
from shared.fipa_codec.languages.l_hfsm import Execute, HierarchicalPlan
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from tests.support.hold import (
    LEFT_OUT,
    Hold,
    HoldPrimitive,
    a_hold,
    hold_leaf,
    hold_s,
    m_hold_still,
    with_hold,
)
from tests.support.messages import communicate
from velma.executor.ledger import read_ledger
from velma.executor.primitives import PRIMITIVES

with contextlib.redirect_stdout(io.StringIO()):
    import gtpyhop

TIMEOUT_S = 60.0
"""For the agents to come alive (ag_ex's loop builds the kitchen), and again for the plan to end."""
HOLD_S = 0.2
AGENTS = ("a_ta", "ag_ex")
ENTRY = "tests.support.hold_agent"


@pytest.fixture
def hold(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[Path]:
    """Hold in every table of this process (taken back afterwards); the file of the
    specification that lets a_ta send it."""
    l_ex = base.LANGUAGES["L_EX"]
    monkeypatch.setitem(base.LANGUAGES, "L_EX", l_ex)
    for t in l_ex.types:
        monkeypatch.setitem(base._BY_TYPE, t, l_ex)
    monkeypatch.setitem(COMMANDS, "hold", Hold)
    add_command(Hold)
    monkeypatch.setitem(PRIMITIVES, Hold, HoldPrimitive)
    monkeypatch.setitem(domain.ACTIONS, "a_hold", a_hold)
    monkeypatch.setitem(LEAVES, "a_hold", hold_leaf)
    monkeypatch.setitem(EXPECTED_S, Hold, hold_s)
    domain.declare()
    gtpyhop_domain = gtpyhop.find_domain_by_name(domain.DOMAIN_NAME)
    monkeypatch.setitem(gtpyhop_domain._action_dict, "a_hold", a_hold)
    monkeypatch.setitem(gtpyhop_domain._task_method_dict, "hold_still", [m_hold_still])
    spec = tmp_path / "spec.toml"
    spec.write_text(with_hold(DEFAULT_SPEC.read_text()))
    for name in ("ROCO_RUN_DIR", "ROCO_SPEC", "ROCO_ACL", LEFT_OUT):
        monkeypatch.delenv(name, raising=False)
    yield spec
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


@dataclass(frozen=True)
class Run:
    """What a fleet's run of the plan left: the final state a_ta reported, every communicate
    a_co heard, and the run folder."""

    final: SWStatus
    seen: list[Communicate]
    run_dir: Path

    def from_ag_ex(self) -> list[tuple[str, object]]:
        """ag_ex's answers: (performative, content)."""
        return [
            (m.performative.value, content(m))
            for m in self.seen
            if m.sender is not None and m.sender.name == "ag_ex"
        ]


class ACo:
    """The test as a_co on Zenoh: keeps every communicate, confirms each of a_ta's reports
    (L_SW), and tells when one says the plan ended."""

    def __init__(self, endpoint: str) -> None:
        self.transport = ZenohTransport([endpoint], links="router")
        self.seen: list[Communicate] = []
        self.final: list[SWStatus] = []
        self.ended = threading.Event()
        self.transport.subscribe(keys.FIPA_ALL, self._heard)
        self.transport.announce(keys.alive_key("a_co"))

    def _heard(self, _key: str, payload: bytes) -> None:
        for one in unpack(payload):
            msg = decode(one)
            self.seen.append(msg)
            said = content(msg)
            if isinstance(said, SWStatus) and msg.receiver[0].name == "a_co":
                self.send(
                    communicate(
                        Performative.CONFIRM,
                        "a_co",
                        "a_ta",
                        "coordinate",
                        msg.conversation_id,
                        in_reply_to=msg.reply_with,
                    )
                )
                if said.state in TERMINAL_SW_STATES:
                    self.final.append(said)
                    self.ended.set()

    def send(self, msg: Communicate) -> None:
        self.transport.publish(keys.fipa_key("C1", "a_co", "a_ta"), encode(msg))

    def heard(self) -> str:
        return "\n".join(f"{m.performative.value} {content(m)}" for m in self.seen)


def run_in_fleet(
    spec: Path, run_dir: Path, plan: HierarchicalPlan, left_out: Mapping[str, Sequence[str]] | None = None
) -> Run:
    """a_ta and ag_ex, each in its own process with Hold's rows but those ``left_out`` names
    per agent (tests/support/hold.py ``TABLES``), run ``plan``, a_co's request, with the
    traffic recorder on; the fleet is stopped before this returns."""
    (run_dir / "logs").mkdir(parents=True)
    env = {
        "ROCO_SPEC": str(spec),
        "ROCO_LINKS": "router",
        "ROCO_PERCEPTION": "truth",
        "ROCO_WORLD": "loop",
        "ROCO_RERUN": "0",
    }
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", env=env, acl=False)
    try:
        fleet.start_router()
        a_co = ACo(fleet.endpoint)
        try:
            fleet.start_recorder()
            for name in AGENTS:
                fleet.env[LEFT_OUT] = ",".join((left_out or {}).get(name, ()))
                fleet.start_service(name, ["-m", ENTRY, name])
            fleet.wait_alive(a_co.transport.session, ("recorder", *AGENTS), timeout=TIMEOUT_S)
            a_co.send(
                communicate(
                    Performative.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec1", plan, reply_with="p1"
                )
            )
            assert a_co.ended.wait(TIMEOUT_S), a_co.heard()
        finally:
            a_co.transport.close()
    finally:
        fleet.stop()
    ended = {name: fleet.processes[name].returncode for name in AGENTS}
    assert ended == dict.fromkeys(AGENTS, 0), ended  # each stopped by SIGTERM, none by an error
    return Run(a_co.final[0], a_co.seen, run_dir)


def conforms(run: Run, spec: Path) -> None:
    """``roco spec verify``'s check of the run folder: the traffic conforms in full to ``spec``,
    and not to the shipped specification, whose C5 requests do not carry Hold."""
    ok, text = verify_report(run.run_dir, spec)
    assert ok, text
    ok, text = verify_report(run.run_dir, DEFAULT_SPEC)
    assert not ok and "Hold" in text, text


@pytest.mark.fleet
def test_a_new_primitive_runs_through_a_pl_and_in_a_fleet_of_a_ta_and_ag_ex(
    hold: Path, tmp_path: Path
) -> None:
    plan = plan_hold()
    assert plan.root.children[0].action == Execute(Hold(duration=HOLD_S))  # type: ignore[arg-type]
    assert expected_s(Hold(duration=HOLD_S)) == HOLD_S
    run = run_in_fleet(hold, tmp_path / "run", plan)
    assert run.final.state is SWState.SUCCEEDED, run.final
    assert Hold(duration=HOLD_S) in [content(m) for m in run.seen if m.receiver[0].name == "ag_ex"]
    (result,) = [c for _, c in run.from_ag_ex() if isinstance(c, CommandResult)]
    assert result.command == "hold" and result.ok, result
    ledger = [(e.event, e.command, e.outcome) for e in read_ledger(run.run_dir).entries]
    assert ledger == [("start", "hold", None), ("end", "hold", "ok")], ledger
    conforms(run, hold)


@pytest.mark.fleet
def test_without_its_executor_row_in_ag_ex_s_process_the_plan_fails(hold: Path, tmp_path: Path) -> None:
    run = run_in_fleet(hold, tmp_path / "run", plan_hold(), {"ag_ex": ["PRIMITIVES"]})
    assert run.final.state is not SWState.SUCCEEDED
    (result,) = [c for _, c in run.from_ag_ex() if isinstance(c, CommandResult)]
    assert not result.ok and "not an executor command: Hold" in (result.reason or ""), result
    conforms(run, hold)


@pytest.mark.fleet
def test_without_its_l_ex_row_in_ag_ex_s_process_ag_ex_does_not_understand_it(
    hold: Path, tmp_path: Path
) -> None:
    run = run_in_fleet(hold, tmp_path / "run", plan_hold(), {"ag_ex": ["COMMANDS"]})
    assert run.final.state is not SWState.SUCCEEDED
    answers = run.from_ag_ex()
    assert sorted(p for p, _ in answers) == ["agree", "not-understood"], answers  # agree: a_ta's subscription
    assert read_ledger(run.run_dir).entries == []  # the robot ran nothing
    conforms(run, hold)


def test_without_its_rows_a_pl_has_no_plan_and_no_leaf(hold: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(LEAVES, "a_hold")
    with pytest.raises(ValueError, match="unknown planner action a_hold"):
        plan_hold()
    monkeypatch.delitem(gtpyhop.find_domain_by_name(domain.DOMAIN_NAME)._action_dict, "a_hold")
    state = gtpyhop.State("test")
    state.steps = 0
    with contextlib.redirect_stdout(io.StringIO()), pytest.raises(Exception, match="Nothing named 'a_hold'"):
        gtpyhop.find_plan(state, [("hold_still", "hold_still", HOLD_S)])


def test_without_its_duration_row_a_ta_expects_the_default(
    hold: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(EXPECTED_S, Hold)
    assert expected_s(Hold(duration=HOLD_S)) == UNTIMED_S
