"""a_co's schedule step: continue the running plan or switch to another (paper Table 3,
after TaskER, Dudek et al.).

Every command has a *cost per second* of waiting: ``1 + priority``, multiplied by
``LATE_FACTOR`` while waiting would make it miss its deadline. A switch from the running task
r to a waiting task n is worth it when what n loses by waiting for r is larger than what r
loses by being interrupted:

    continue:  c_n · remaining(r)
    switch:    c_r · (duration(n) + interruption(r)) + SWITCH_COST

where ``remaining(r)`` is the expected time of r's plan still to run (s), ``duration(n)`` the
expected time of n's plan, and ``interruption(r)`` what the interruption adds to r (putting
held objects down safely and taking them again, estimated by the planner's safe-stop cost
plus ``RESUME_OVERHEAD_S``). Costs are in "priority-weighted seconds". Pure functions, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan

LATE_FACTOR = 10.0
"""Waiting that makes a command miss its deadline costs this many times more per second."""
SWITCH_COST = 10.0
"""Fixed cost of any switch (priority-weighted s): equal commands do not swap back and forth."""
RESUME_OVERHEAD_S = 15.0
"""Expected extra time (s) to resume an interrupted plan: replanning, taking held objects
again (beyond the safe stop itself)."""


@dataclass(frozen=True)
class Candidate:
    """A command as the schedule step sees it: ``duration_s`` the expected execution time of
    its plan (s), ``deadline_in_s`` seconds left to its deadline (None: none), ``order`` the
    order of acceptance (ties go to the earlier command)."""

    task_id: str
    priority: int
    duration_s: float
    deadline_in_s: float | None = None
    order: int = 0


@dataclass(frozen=True)
class Running:
    """The command a_ta runs: expected ``remaining_s`` of its plan and the expected time
    ``interruption_s`` a safe stop takes now (s)."""

    task: Candidate
    remaining_s: float
    interruption_s: float = 0.0


@dataclass(frozen=True)
class Decision:
    """``switch_to`` the task to start (None: continue); ``preempt`` True when the running
    task must be cancelled first; ``reason`` in words, with the compared costs."""

    switch_to: str | None
    preempt: bool
    reason: str


def plan_left(plan: HierarchicalPlan, leaf: int) -> tuple[float, float]:
    """What is left of ``plan`` while a_ta runs its leaf number ``leaf`` (0-based): the
    expected time (s) of the leaves still to run, ``remaining(r)``, and that of the safe stop
    a_ta would run if cancelled now (the safe-stop HFSM the leaf's ``on_cancel`` names; 0 when
    it names none), the planner's part of ``interruption(r)``."""
    leaves = plan.root.leaves()[leaf:]
    remaining = sum(node.duration for _, node in leaves)
    key = leaves[0][1].on_cancel if leaves else None
    stop = plan.safe_stops.get(key) if key is not None else None
    stopping = sum(node.duration for _, node in stop.leaves()) if stop is not None else 0.0
    return remaining, stopping


def cost_per_second(task: Candidate, waiting_s: float) -> float:
    """Cost of one second of waiting for ``task`` if it waits ``waiting_s`` before it starts."""
    c = 1.0 + max(0, task.priority)
    if task.deadline_in_s is not None and waiting_s + task.duration_s > task.deadline_in_s:
        c *= LATE_FACTOR
    return c


def best(waiting: list[Candidate]) -> Candidate:
    """The waiting command to run first when the robot is free: the highest cost per second
    of waiting (priority, deadline at risk), then the earliest accepted. Raises ValueError
    for an empty list."""
    if not waiting:
        raise ValueError("no waiting command")
    return min(waiting, key=lambda t: (-cost_per_second(t, 0.0), t.order))


def decide(running: Running | None, waiting: list[Candidate]) -> Decision:
    """The schedule step (see module docstring). With nothing running, start the best
    waiting command; with nothing waiting, continue."""
    if not waiting:
        return Decision(None, False, "nothing waits")
    n = best(waiting)
    if running is None:
        return Decision(n.task_id, False, f"the robot is free: start {n.task_id}")
    r = running.task
    cont = cost_per_second(n, running.remaining_s) * running.remaining_s
    delay_r = n.duration_s + running.interruption_s + RESUME_OVERHEAD_S
    r_later = Candidate(r.task_id, r.priority, running.remaining_s, r.deadline_in_s, r.order)
    switch = cost_per_second(r_later, delay_r) * delay_r + SWITCH_COST
    numbers = f"continue {cont:.0f} vs switch {switch:.0f}"
    if switch < cont:
        return Decision(n.task_id, True, f"preempt {r.task_id} for {n.task_id}: {numbers}")
    return Decision(None, False, f"continue {r.task_id}: {numbers}")
