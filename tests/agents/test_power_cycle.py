"""The robot power-cycled between two commands, on the agents themselves (MemoryBus,
kinematic robot double): ag_ex tells a_ta the new power-on (or its answers name it), a_ta
reports it, renews a_km's picture of the kitchen from a fresh observation, and the next command
succeeds. The fleet
version (a world process started anew) is tests/integration/test_power_cycle.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.agents.executor.agent import ExecutorAgent
from services.agents.task_executor.agent import TaskExecutor
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec.languages.l_ex import CommandResult, PowerOn
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_sw import SWState
from shared.fipa_codec.languages.l_wm import WorldUpdate
from tests.agents.test_coordination import Session
from tests.support.fake_executor import FakeExecutor
from velma.world.files import LINK_FILE, LinkWatch, write_whole


class PowerCycled(FakeExecutor):
    """The kinematic double as a robot that can be power-cycled: the kitchen as it starts, the
    time from 0, a new ``world_link`` (which ag_ex names in its answers)."""

    def __init__(self) -> None:
        super().__init__()
        self.world_link = "power-on-1"

    def power_cycle(self) -> None:
        FakeExecutor.__init__(self)
        self.world_link = "power-on-2"


def test_after_a_power_cycle_a_km_is_renewed_and_the_next_pour_succeeds() -> None:
    robot = PowerCycled()
    with Session(robot) as s:
        s.wait_for_initial_knowledge()
        s.say("pour the jar into the bowl", "first")
        assert s.final("first").kind.value == "succeeded", s.by_request["first"]
        assert robot.inside["bowl"] > 0
        robot.power_cycle()
        s.say("pour the jar into the bowl", "second")
        assert s.final("second").kind.value == "succeeded", s.by_request["second"]
        assert robot.inside["bowl"] > 0 and robot.inside["jar"] == 0
        renewals = [c for k, m, c in s.traffic() if isinstance(c, WorldUpdate) and c.renews]
        replans = [c.reason or "" for c in s.sw_states() if c.state is SWState.REPLAN]
    assert len(renewals) == 1, renewals
    assert any("power-cycled" in r for r in replans), replans
    (a_ta,) = [a for a in s.agents if a.name == "a_ta"]
    assert a_ta.counters["world_restarts"] == 1


def test_told_the_new_power_on_a_ta_renews_a_km_before_the_next_plan(tmp_path: Path) -> None:
    """ag_ex watches the run folder's link name (as in a fleet, here a folder of the test's):
    the new one is told to a_ta's subscription (L_EX PowerOn) before any command and a_km's
    picture is renewed then; the next pour's plan may have been made before (a_ta cannot tell),
    so its first answer ends it in Replan, and the pour planned again succeeds."""
    robot = PowerCycled()
    write_whole(tmp_path / LINK_FILE, b"power-on-1\n")
    with Session(robot) as s:
        ag_ex = s.agent("ag_ex")
        assert isinstance(ag_ex, ExecutorAgent)
        ag_ex.link_watch = LinkWatch(tmp_path, "power-on-1", period_s=0.05)
        s.wait_for_initial_knowledge()
        s.say("pour the jar into the bowl", "first")
        assert s.final("first").kind.value == "succeeded", s.by_request["first"]
        robot.power_cycle()
        write_whole(tmp_path / LINK_FILE, b"power-on-2\n")
        s.wait_for(lambda _k, _m, c: isinstance(c, WorldUpdate) and c.renews)
        s.say("pour the jar into the bowl", "second")
        assert s.final("second").kind.value == "succeeded", s.by_request["second"]
        replans = [c.reason or "" for c in s.sw_states() if c.state is SWState.REPLAN]
        renewals = [c for k, m, c in s.traffic() if isinstance(c, WorldUpdate) and c.renews]
    assert len([r for r in replans if "power-cycled" in r]) == 1, replans
    assert len(renewals) == 1
    assert ag_ex.counters["world_restarts"] == 1


def test_a_late_answer_from_the_world_before_is_no_new_power_on(monkeypatch: pytest.MonkeyPatch) -> None:
    """A command the power cycle ended answers ``stopped`` from the old world's loop after ag_ex
    told the new one: a_ta does not take the old world for a newer power-on."""
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    a_ta = TaskExecutor(MemoryBus().transport())
    observed: list[bool] = []
    monkeypatch.setattr(a_ta, "_observe_initial", lambda: observed.append(True))
    assert not a_ta._started_anew(PowerOn(world="power-on-1"))  # the first: a baseline
    assert a_ta._started_anew(PowerOn(world="power-on-2"))
    late = CommandResult(command="tilt", ok=False, reason="stopped", world="power-on-1")
    assert not a_ta._started_anew(late)
    assert not a_ta._started_anew(CommandResult(command="wait", ok=True, world="power-on-2"))
    assert a_ta._started_anew(PowerOn(world="power-on-3"))
    assert a_ta.counters["world_restarts"] == 2 and observed == [True, True]


def test_a_late_observation_of_the_world_before_is_not_sent_to_a_km(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A look the power cycle caught answers late from the old loop, after ag_ex told the new
    power-on: its robot time (later than the new kitchen's) would make a_km take every
    observation of the new kitchen for stale, and a_pl plan looks at the old kitchen's poses
    over and over. a_ta sends a_km only the new kitchen's observation, which renews it."""
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    a_ta = TaskExecutor(MemoryBus().transport())
    sent: list[WorldUpdate] = []
    monkeypatch.setattr(a_ta, "_observe_initial", lambda: None)
    monkeypatch.setattr(a_ta, "_inform_km", sent.append)
    a_ta.subscription = object()  # type: ignore[assignment]  # a_km subscribed
    a_ta._started_anew(PowerOn(world="power-on-1"))
    a_ta._update_km(Observation(stamp=268.0, objects=(), world="power-on-1"))
    assert a_ta._started_anew(PowerOn(world="power-on-2"))
    a_ta._update_km(Observation(stamp=270.0, objects=(), world="power-on-1"))  # late, of the kitchen before
    a_ta._update_km(Observation(stamp=3.0, objects=(), world="power-on-2"))
    assert [(u.stamp, u.renews) for u in sent] == [(268.0, False), (3.0, True)]
    assert a_ta.counters["observations_of_world_before"] == 1
