"""a_co's schedule step (services/agents/coordinator/scheduling.py): continue or switch by the
TaskER-style comparison of priority-weighted waiting costs."""

from __future__ import annotations

import pytest

from services.agents.coordinator.scheduling import (
    LATE_FACTOR,
    SWITCH_COST,
    Candidate,
    Running,
    best,
    cost_per_second,
    decide,
    plan_left,
)
from shared.fipa_codec.languages.l_ex import Wait
from shared.fipa_codec.languages.l_hfsm import Execute, HierarchicalPlan, PlanNode

pytestmark = pytest.mark.requirement("R1.2")


def running(priority: int = 0, remaining: float = 60.0, interruption: float = 10.0) -> Running:
    return Running(Candidate("pour", priority, remaining, order=0), remaining, interruption)


def test_a_free_robot_starts_the_most_urgent_command() -> None:
    waiting = [Candidate("a", 0, 20.0, order=0), Candidate("b", 3, 50.0, order=1)]
    d = decide(None, waiting)
    assert d.switch_to == "b" and not d.preempt


def test_equal_priority_commands_run_in_order_of_acceptance() -> None:
    assert best([Candidate("late", 0, 5.0, order=2), Candidate("early", 0, 50.0, order=1)]).task_id == "early"


@pytest.mark.requirement("R2.1")
def test_an_urgent_command_preempts_a_long_running_task() -> None:
    d = decide(running(priority=0, remaining=60.0), [Candidate("cup", 5, 25.0, order=1)])
    assert d.switch_to == "cup" and d.preempt
    assert "preempt pour for cup" in d.reason


def test_an_equal_priority_command_waits() -> None:
    d = decide(running(priority=0, remaining=60.0), [Candidate("cup", 0, 25.0, order=1)])
    assert d.switch_to is None and not d.preempt


def test_an_urgent_command_waits_when_the_running_task_is_nearly_done() -> None:
    d = decide(running(priority=0, remaining=2.0), [Candidate("cup", 5, 25.0, order=1)])
    assert d.switch_to is None


def test_a_deadline_at_risk_makes_an_equal_priority_command_preempt() -> None:
    n = Candidate("cup", 0, 25.0, deadline_in_s=40.0, order=1)
    assert cost_per_second(n, 60.0) == pytest.approx(LATE_FACTOR)
    d = decide(running(priority=0, remaining=60.0), [n])
    assert d.switch_to == "cup" and d.preempt


def test_the_switch_cost_keeps_near_equal_costs_from_switching() -> None:
    # continue: 1 × 40 = 40; switch: 1 × (15 + 0 + 15) + SWITCH_COST = 30 + SWITCH_COST
    d = decide(running(priority=0, remaining=40.0, interruption=0.0), [Candidate("n", 0, 15.0, order=1)])
    assert (d.switch_to is None) == (30 + SWITCH_COST >= 40)


def test_nothing_waiting_continues() -> None:
    assert decide(running(), []).switch_to is None
    with pytest.raises(ValueError):
        best([])


def test_what_is_left_of_a_plan_is_its_leaves_to_run_and_the_safe_stop_of_the_leaf_it_runs() -> None:
    def leaf(name: str, duration: float, on_cancel: str | None = None) -> PlanNode:
        return PlanNode(
            name=name, action=Execute(Wait(duration=duration)), duration=duration, on_cancel=on_cancel
        )

    put_down = PlanNode(name="put_down", children=(leaf("lower", 4.0), leaf("open", 1.5)))
    plan = HierarchicalPlan(
        plan_id="p",
        task_id="t",
        root=PlanNode(
            name="pour", children=(leaf("take", 10.0), leaf("tilt", 5.0, "held"), leaf("back", 3.0))
        ),
        safe_stops={"held": put_down},
    )
    assert plan_left(plan, 0) == (18.0, 0.0)  # the first leaf names no safe stop
    assert plan_left(plan, 1) == (8.0, 5.5)  # the tilt's: put the jar down
    assert plan_left(plan, 2) == (3.0, 0.0)
    assert plan_left(plan, 3) == (0.0, 0.0)  # every leaf has run
