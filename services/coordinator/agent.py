"""a_co — the coordinator (paper §5.5, Table 3, Figure 11a).

FSM states: trigger (idle; a_hi commands and a_ta states arrive), procReq (store the task,
compute its deadline and start time), compSP (request plans from a_pl for every task awaiting
execution, collect them), schedule (decide continue or switch), switch (start a plan on a_ta
with the coordinate protocol). Communicates from a_ta are handled in every state; each L_SW
inform is confirmed (paper §5.4).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Arc, Behaviour
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure
from shared.fipa_codec.languages.l_sw import SWState, SWStatus

PLAN_REPLY_BY_S = 600.0
MAX_PLANS_PER_TASK = 6
"""Plans a_co orders for one command before it gives up (replanning must converge)."""
DEFAULT_DEADLINE_S = 3600.0


@dataclass
class Task:
    """A command being coordinated. ``task_id`` is the C2 conversation-id."""

    task_id: str
    command: HumanCommand
    request: Received
    accepted_at: float
    deadline: float
    plan_index: int = 0
    plan: HierarchicalPlan | None = None
    needs_plan: bool = True
    planning: str | None = None  # reply-with of the outstanding plan request
    running: bool = False


class Coordinator(Agent):
    name = "a_co"

    def build_fsm(self) -> FSM:
        self.tasks: dict[str, Task] = {}
        self.ta_task: str | None = None  # task whose plan a_ta runs
        self.ta_conversation: str | None = None
        self.decision = "continue"
        return FSM(
            initial="trigger",
            states={
                "trigger": Behaviour(
                    "trigger",
                    self._trigger,
                    terminal=self._has_work,
                    doc="idle: receive commands from a_hi and a_ta's states",
                ),
                "procReq": Behaviour(
                    "procReq",
                    self._proc_req,
                    terminal=lambda: True,
                    waits=False,
                    doc="store the new tasks; compute deadline and start time",
                ),
                "compSP": Behaviour(
                    "compSP",
                    self._comp_sp_step,
                    terminal=self._plans_collected,
                    on_enter=self._request_plans,
                    doc="request plans of all waiting tasks from a_pl; collect them",
                ),
                "schedule": Behaviour(
                    "schedule",
                    self._schedule,
                    terminal=lambda: True,
                    waits=False,
                    doc="decide: switch the plan a_ta runs, or continue",
                ),
                "switch": Behaviour(
                    "switch",
                    self._switch,
                    terminal=lambda: True,
                    waits=False,
                    doc="start the chosen plan on a_ta (coordinate protocol)",
                ),
            },
            arcs=[
                Arc("trigger", "procReq", self._new_command, "new command"),
                Arc("trigger", "compSP", self._plans_needed, "plan needed"),
                Arc("trigger", "schedule", lambda: True, "a_ta changed"),
                Arc("procReq", "compSP"),
                Arc("compSP", "schedule"),
                Arc("schedule", "switch", lambda: self.decision == "switch", "switch"),
                Arc("schedule", "trigger", lambda: self.decision == "continue", "continue"),
                Arc("switch", "trigger"),
            ],
        )

    # ---- conditions ----
    def _new_command(self) -> bool:
        return any(self._is_command(i) for i in self.x)

    @staticmethod
    def _is_command(item: Received) -> bool:
        return item.sender == "a_hi" and item.performative is Performative.REQUEST

    def _plans_needed(self) -> bool:
        return any(t.needs_plan and t.planning is None for t in self.tasks.values())

    def _ready_to_start(self) -> bool:
        return self.ta_task is None and any(t.plan is not None and not t.running for t in self.tasks.values())

    def _has_work(self) -> bool:
        return self._new_command() or self._plans_needed() or self._ready_to_start()

    def _plans_collected(self) -> bool:
        return all(t.planning is None for t in self.tasks.values())

    # ---- behaviours ----
    def _trigger(self) -> None:
        self._handle_async()

    def _proc_req(self) -> None:
        while (item := self.take(self._is_command)) is not None:
            if not isinstance(item.content, HumanCommand):
                self.reply(
                    item,
                    Performative.REFUSE,
                    CommandOutcome(command_id="", succeeded=False, detail="no command in the request"),
                )
                continue
            now = time.time()
            task_id = item.msg.conversation_id or f"task-{len(self.tasks)}"
            deadline = now + (item.content.deadline_s or DEFAULT_DEADLINE_S)
            self.tasks[task_id] = Task(task_id, item.content, item, now, deadline)
            self.reply(item, Performative.AGREE)
            self.log.info("task %s: %s (priority %d)", task_id, item.content.text, item.content.priority)

    def _request_plans(self) -> None:
        for task in list(self.tasks.values()):
            if task.needs_plan and task.planning is None:
                if task.plan_index >= MAX_PLANS_PER_TASK:
                    self._finish(task, False, f"no progress after {task.plan_index} plans")
                    continue
                task.plan_index += 1
                gtn = GroundTaskNetwork(
                    task_id=task.task_id, tasks=(task.command.goal,), plan_index=task.plan_index
                )
                msg = self.send(
                    "a_pl",
                    Performative.REQUEST,
                    gtn,
                    protocol="fipa-request",
                    conversation_id=f"{task.task_id}-plan{task.plan_index}",
                    reply_by_s=PLAN_REPLY_BY_S,
                )
                task.planning = msg.reply_with
                self.log.info("task %s: requested plan #%d", task.task_id, task.plan_index)

    def _comp_sp_step(self) -> None:
        self._handle_async()

    def _schedule(self) -> None:
        self._handle_async()
        self.decision = "switch" if self._ready_to_start() else "continue"

    def _switch(self) -> None:
        candidates = [t for t in self.tasks.values() if t.plan is not None and not t.running]
        # Highest priority first, then earliest deadline (TaskER-style ordering; preemption of a
        # running plan is not needed while one command runs at a time).
        task = min(candidates, key=lambda t: (-t.command.priority, t.deadline))
        assert task.plan is not None
        msg = self.send(
            "a_ta",
            Performative.REQUEST,
            task.plan,
            protocol="coordinate",
            conversation_id=f"{task.task_id}-exec{task.plan_index}",
            expect_reply=True,
        )
        task.running = True
        self.ta_task = task.task_id
        self.ta_conversation = msg.conversation_id
        self.log.info("task %s: plan %s sent to a_ta", task.task_id, task.plan.plan_id)

    # ---- communicates that may arrive in any state ----
    def _handle_async(self) -> None:
        for item in list(self.x):
            if item.sender == "a_ta":
                self.x.remove(item)
                self._from_ta(item)
            elif item.sender == "a_pl":
                self.x.remove(item)
                self._from_pl(item)
        self.reject_unhandled(self._is_command)

    def _task_by_reply(self, in_reply_to: str | None) -> Task | None:
        for t in self.tasks.values():
            if t.planning is not None and t.planning == in_reply_to:
                return t
        return None

    def _from_pl(self, item: Received) -> None:
        task = self._task_by_reply(item.msg.in_reply_to)
        if task is None:
            if item.performative is not Performative.NOT_UNDERSTOOD:
                self.not_understood(item.sender, item.channel, "no such plan request", item.msg)
            return
        if item.performative is Performative.AGREE:
            return
        task.planning = None
        if item.performative is Performative.INFORM and isinstance(item.content, HierarchicalPlan):
            task.plan = item.content
            task.needs_plan = False
            self.log.info(
                "task %s: plan #%d received (%s, %d km queries)",
                task.task_id,
                task.plan_index,
                "complete" if item.content.complete else "partial",
                item.content.km_queries,
            )
            return
        reason = (
            item.content.reason
            if isinstance(item.content, PlanFailure)
            else item.msg.content.decode("utf-8", "replace")
        )
        self._finish(task, False, f"no plan: {reason}")

    def _from_ta(self, item: Received) -> None:
        task = self.tasks.get(self.ta_task or "")
        in_conversation = item.msg.conversation_id == self.ta_conversation
        if item.performative is Performative.INFORM and isinstance(item.content, SWStatus):
            self.reply(item, Performative.CONFIRM)
            if not in_conversation or task is None:
                return
            status = item.content
            self.log.info("a_ta %s %s", status.state.value, status.step or "")
            if status.state is SWState.SUCCEEDED:
                self._finish(task, True, "the task succeeded")
            elif status.state is SWState.REPLAN or status.state is SWState.PREEMPTED:
                task.running, task.plan, task.needs_plan = False, None, True
                self._release_ta()
            elif status.state is SWState.ERROR:
                self._finish(task, False, f"execution failed: {status.reason or 'unknown error'}")
            return
        if item.performative in (Performative.FAILURE, Performative.REFUSE, Performative.NOT_UNDERSTOOD):
            if in_conversation and task is not None:
                self._finish(
                    task,
                    False,
                    f"a_ta {item.performative.value}: {item.msg.content.decode('utf-8', 'replace')}",
                )
            return
        self.not_understood(item.sender, item.channel, f"unexpected {item.performative.value}", item.msg)

    def _release_ta(self) -> None:
        if self.ta_conversation is not None:
            self.conversations.forget_conversation(self.ta_conversation)
        self.ta_task = None
        self.ta_conversation = None

    def _finish(self, task: Task, succeeded: bool, detail: str) -> None:
        outcome = CommandOutcome(command_id=task.task_id, succeeded=succeeded, detail=detail)
        self.reply(task.request, Performative.INFORM if succeeded else Performative.FAILURE, outcome)
        self.log.info("task %s %s: %s", task.task_id, "succeeded" if succeeded else "failed", detail)
        if self.ta_task == task.task_id:
            self._release_ta()
        del self.tasks[task.task_id]
