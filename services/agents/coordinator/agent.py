"""a_co — the coordinator (paper §5.5, Table 3, Figure 11a).

FSM states: trigger (idle; a_hi's commands, cancels, subscriptions and queries and a_ta's
states arrive), procReq (store new commands with priority and deadline; stop cancelled
ones), compSP (request plans from a_pl for every command that needs one, collect them),
schedule (continue the running plan or switch: services/agents/coordinator/scheduling.py, after
TaskER), switch (the coordinate protocol on C1: ``cancel`` the running plan — a_ta goes
Terminating, puts held objects down safely, reports Preempted — or ``request`` a_ta to run
the chosen plan). Communicates from a_ta and a_pl are handled in every state; each L_SW
inform is confirmed (paper §5.4).

A preempted command is planned again from the world as it then is and resumed when the
schedule picks it. Whenever a_ta ends a plan the world has changed, so the plans of waiting
commands are dropped and made again before they run.

Towards the person (C2, L_HC): commands by fipa-request (agree, then inform or failure with a
CommandOutcome; a ``cancel`` stops a command and is answered once the robot is safe), progress
by fipa-subscribe (a Progress inform at every change), status by fipa-query (Status).
Every subscribe is answered, however late it comes: agree (or refuse for content other than a
ProgressSubscription); the latest agreed subscription is the one progress goes to. Progress
made while none is agreed — before the person's interface subscribes or while its subscribe
waits, after it cancels or did not understand — is kept, in order, and sent as informs right
after the next agree (FIPA SC00035: informs follow the agree), so that no change is lost
whenever the subscription comes. What is kept is bounded: ``PROGRESS_KEPT_PER_COMMAND``
reports per command and ``PROGRESS_KEPT`` in all; past a bound the oldest report goes (counted
as ``progress_dropped``).

Restarts (docs/recovery.md): every accepted command is kept in a_co's state file
(services/runtime/state_store.py) after the step that agreed to it, with the plan a_ta runs,
the progress subscription and the progress not yet sent; a restarted a_co reloads them,
re-enters their conversations and plans again what was being planned. A copy of a command it
already holds (a_hi retransmits until it hears the agree) is not accepted twice (the role
recognises it: services/runtime/roles.py). When a_ta's
liveliness token disappears while it runs a plan and comes back, a restarted a_ta that kept its
plan reports Replan in the same conversation. a_co also sends its last confirm of that
conversation again: the same a_ta (the token only looked gone, e.g. while the router restarted)
drops the copy, a restarted a_ta answers not-understood, and a_co then plans the command again.
Plan requests to a_pl are retransmitted until answered, so an a_pl that restarts gets them
again.
"""

from __future__ import annotations

import itertools
import time
from collections import deque
from dataclasses import dataclass
from typing import Literal

import msgspec

from services.agents.coordinator.scheduling import Candidate, Decision, Running, decide
from services.runtime.agent import RESEND_ON_RETURN, Agent, Received
from services.runtime.behaviour import FSM, Arc, Behaviour
from services.runtime.roles import (
    INITIATOR,
    PARTICIPANT,
    Conversation,
    RestoreError,
    handles,
    initiator,
    participant,
)
from services.runtime.state_store import StateFile
from services.spec.names import (
    C1,
    C2,
    C3,
    COORDINATE,
    FIPA_QUERY,
    FIPA_REQUEST,
    FIPA_SUBSCRIBE,
    L_HC,
    L_HFSM,
    L_SW,
)
from shared.fipa_codec import DecodeError, Performative, decode, encode
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    ProgressSubscription,
    Status,
    StatusQuery,
    TaskState,
    TaskStatus,
)
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure, PlanNode
from shared.fipa_codec.languages.l_sw import SWState, SWStatus

PLAN_REPLY_BY_S = 600.0
PLAN_RETRY_S = 5.0
"""Retransmission period of a plan request until a_pl answers (it may be restarting)."""
MAX_REPLANS_PER_TASK = 6
"""Replan reports a_co accepts for one command before it gives up (replanning must converge)."""
PROGRESS_KEPT_PER_COMMAND = 256
"""Progress reports a_co keeps for one command while no subscription is agreed (a pour's two
plans make about 80)."""
PROGRESS_KEPT = 1024
"""Progress reports a_co keeps in all while no subscription is agreed."""

_ON_TA = (TaskState.RUNNING, TaskState.TERMINATING)


@dataclass
class Task:
    """A command being coordinated. ``task_id`` is the C2 conversation-id; ``deadline`` a
    POSIX time (None: none); ``order`` the order of acceptance."""

    task_id: str
    command: HumanCommand
    request: Conversation
    accepted_at: float
    deadline: float | None
    order: int
    state: TaskState = TaskState.WAITING
    plan: HierarchicalPlan | None = None
    plan_index: int = 0
    replans: int = 0
    needs_plan: bool = True
    planning: Conversation | None = None  # the outstanding plan request to a_pl
    step: str | None = None
    leaf: int = 0  # index of the leaf a_ta runs
    cancel: Received | None = None  # the person's cancel, answered when the robot is safe
    detail: str = ""


class KeptTask(msgspec.Struct, kw_only=True):
    """One accepted command as a_co keeps it across a restart: the person's request and
    cancel as encoded communicates (FIPA SC00061 msgpack), times as POSIX s."""

    request: bytes
    accepted_at: float
    deadline: float | None
    order: int
    state: TaskState
    plan: HierarchicalPlan | None
    plan_index: int
    replans: int
    step: str | None
    leaf: int
    cancel: bytes | None
    detail: str


class KeptCoordinator(msgspec.Struct, kw_only=True):
    """a_co's state file: the commands, what a_ta runs (``ta_task``, the C1 conversation, its
    reply-with, whether it was cancelled), a_hi's progress subscription and the progress made
    while none was agreed, oldest first (``unsent``; absent in files of earlier versions)."""

    tasks: list[KeptTask]
    ta_task: str | None
    ta_conversation: str | None
    ta_cancelled: bool
    subscription: bytes | None
    unsent: list[Progress] = msgspec.field(default_factory=list)


PersonSaid = tuple[Literal["command", "stop"], Conversation, Received]
"""What the person said, for procReq: a command (its request) or a stop (its cancel)."""


class Coordinator(Agent):
    name = "a_co"
    ROLES = (
        participant(C2, FIPA_REQUEST, L_HC),
        participant(C2, FIPA_SUBSCRIBE, L_HC),
        participant(C2, FIPA_QUERY, L_HC),
        initiator(C3, FIPA_REQUEST, L_HFSM, reply_by_s=PLAN_REPLY_BY_S, retry_s=PLAN_RETRY_S),
        # a plan sent while a_ta (or the robot's router) is gone goes again when a_ta's token
        # reappears, until a_ta answers (docs/recovery.md, "Across two hosts")
        initiator(C1, COORDINATE, L_HFSM, L_SW, retry_s=RESEND_ON_RETURN),
    )

    def build_fsm(self) -> FSM:
        self.kept = StateFile.for_agent(self.name, KeptCoordinator)
        self._kept_as: tuple[object, ...] | None = None  # signature of what was last written
        self.ta_lost = False  # a_ta's token disappeared while it ran a plan
        self.tasks: dict[str, Task] = {}
        self.ta_task: str | None = None  # task whose plan a_ta runs (or is terminating)
        self.ta: Conversation | None = None  # the C1 conversation of the plan a_ta runs
        self.ta_cancelled = False  # cancel sent in the current C1 conversation
        self.person: deque[PersonSaid] = deque()  # commands and stops for procReq
        self.subscription: Conversation | None = None  # a_hi's progress subscription
        self.unsent: deque[Progress] = deque()  # progress made while no subscription was agreed
        self.unsent_changes = 0  # counts changes of ``unsent`` (the state file's signature)
        self.decision: Decision = Decision(None, False, "")
        self.reschedule = False
        self.decisions: list[Decision] = []
        self._order = itertools.count()
        self.rerun = self.hooks.queue(self.name) if self.hooks else None  # a viewer: runtime/hooks.py
        return FSM(
            [
                Behaviour(
                    "trigger",
                    self._trigger,
                    terminal=self._has_work,
                    doc="idle: receive commands from a_hi and a_ta's states",
                ),
                Behaviour(
                    "procReq",
                    self._proc_req,
                    terminal=lambda: True,
                    waits=False,
                    doc="store new commands (priority, deadline); stop cancelled ones",
                ),
                Behaviour(
                    "compSP",
                    self._comp_sp_step,
                    terminal=self._plans_collected,
                    on_enter=self._request_plans,
                    doc="request plans of all waiting commands from a_pl; collect them",
                ),
                Behaviour(
                    "schedule",
                    self._schedule,
                    terminal=lambda: True,
                    waits=False,
                    doc="decide from the plans' costs: continue, or switch the plan a_ta runs",
                ),
                Behaviour(
                    "switch",
                    self._switch,
                    terminal=lambda: True,
                    waits=False,
                    doc="coordinate protocol on C1: cancel the running plan, or start the chosen one",
                ),
            ],
            arcs=[
                Arc("trigger", "procReq", self._person_spoke, "command or cancel"),
                Arc("trigger", "compSP", self._plans_needed, "plan needed"),
                Arc("trigger", "schedule", lambda: True, "plan ready or a_ta changed"),
                Arc("procReq", "compSP"),
                Arc("compSP", "schedule"),
                Arc("schedule", "switch", lambda: self.decision.switch_to is not None, "switch"),
                Arc("schedule", "trigger", lambda: self.decision.switch_to is None, "continue"),
                Arc("switch", "trigger"),
            ],
        )

    # ---- conditions ----
    def _person_spoke(self) -> bool:
        return bool(self.person)

    def _plans_needed(self) -> bool:
        return any(t.needs_plan and t.planning is None and t.state not in _ON_TA for t in self.tasks.values())

    def _robot_free(self) -> bool:
        return self.ta_task is None

    def _has_work(self) -> bool:
        return self._person_spoke() or self._plans_needed() or self.reschedule

    def _plans_collected(self) -> bool:
        return all(t.planning is None for t in self.tasks.values())

    # ---- behaviours ----
    def _trigger(self) -> None:
        self.handle_received()

    def _proc_req(self) -> None:
        self.handle_received()
        while self.person:
            kind, conv, item = self.person.popleft()
            if kind == "command":
                self._accept(conv, item)
            else:
                self._stop_command(conv, item)

    def _accept(self, conv: Conversation, item: Received) -> None:
        if not isinstance(item.content, HumanCommand):
            conv.refuse_with(Performative.REFUSE, "no command in the request")
            return
        now = time.time()
        task_id = conv.conversation_id or f"task-{len(self.tasks)}"
        if task_id in self.tasks:  # (the same request again is the role's: services/runtime/roles.py)
            conv.refuse_with(Performative.REFUSE, f"command {task_id} is already being carried out")
            return
        deadline = now + item.content.deadline_s if item.content.deadline_s is not None else None
        task = Task(task_id, item.content, conv, now, deadline, next(self._order))
        self.tasks[task_id] = task
        conv.reply(Performative.AGREE)
        self._progress(task, TaskState.WAITING, detail="accepted")
        self.log.info("task %s: %s (priority %d)", task_id, item.content.text, item.content.priority)

    def _stop_command(self, conv: Conversation, cancel: Received) -> None:
        """The person cancels command ``conv`` (FIPA cancel meta-protocol: answered by
        inform when stopped, failure when it cannot be)."""
        task = self.tasks.get(conv.conversation_id)
        if task is None:
            conv.refuse_with(Performative.FAILURE, "no such command (it may have ended already)", to=cancel)
            return
        task.cancel = cancel
        if task.task_id == self.ta_task:
            self._cancel_ta(f"stopped by the person: {task.command.text}")
            return
        if task.planning is not None:
            task.planning.abandon()
        self._finish(task, False, "stopped; the robot was not working on it", stopped=True)

    def _request_plans(self) -> None:
        for task in list(self.tasks.values()):
            if not (task.needs_plan and task.planning is None and task.state not in _ON_TA):
                continue
            if task.replans > MAX_REPLANS_PER_TASK:
                self._finish(task, False, f"no progress after {task.replans} replans")
                continue
            task.plan_index += 1
            gtn = GroundTaskNetwork(
                task_id=task.task_id, tasks=(task.command.goal,), plan_index=task.plan_index
            )
            task.planning = self.roles.open(
                C3, FIPA_REQUEST, gtn, conversation_id=f"{task.task_id}-plan{task.plan_index}"
            )
            if task.state is not TaskState.PREEMPTED:
                self._progress(task, TaskState.PLANNING, detail=f"plan #{task.plan_index} requested")
            self.log.info("task %s: requested plan #%d", task.task_id, task.plan_index)

    def _comp_sp_step(self) -> None:
        self.handle_received()

    def _schedule(self) -> None:
        self.handle_received()
        self.reschedule = False
        now = time.time()
        waiting = [
            self._candidate(t, now, t.plan.cost)
            for t in self.tasks.values()
            if t.plan is not None and t.state not in _ON_TA
        ]
        running: Running | None = None
        if self.ta_task is not None:
            if self.ta_cancelled:  # a_ta is on its way to a safe state: wait for Preempted
                self.decision = Decision(None, False, "a_ta is terminating")
                return
            r = self.tasks.get(self.ta_task)
            if r is not None and r.plan is not None:
                leaves = r.plan.root.leaves()
                remaining = sum(n.duration for _, n in leaves[r.leaf :])
                running = Running(
                    self._candidate(r, now, remaining), remaining, self._interruption(r, leaves)
                )
        self.decision = decide(running, waiting)
        if self.decision.switch_to is not None:
            self.decisions.append(self.decision)
            self.log.info("schedule: %s", self.decision.reason)

    def _candidate(self, task: Task, now: float, duration: float) -> Candidate:
        left = task.deadline - now if task.deadline is not None else None
        return Candidate(task.task_id, task.command.priority, duration, left, task.order)

    @staticmethod
    def _interruption(task: Task, leaves: list[tuple[str, PlanNode]]) -> float:
        """Expected time (s) of the safe stop a_ta would run if cancelled now."""
        assert task.plan is not None
        for _, node in leaves[task.leaf :]:
            if node.on_cancel is not None:
                stop = task.plan.safe_stops.get(node.on_cancel)
                return sum(n.duration for _, n in stop.leaves()) if stop is not None else 0.0
            return 0.0
        return 0.0

    def _switch(self) -> None:
        if self.decision.preempt:
            running = self.tasks.get(self.ta_task or "")
            chosen = self.tasks.get(self.decision.switch_to or "")
            why = f"preempted for “{chosen.command.text}”" if chosen else "preempted"
            if running is not None:
                running.detail = why
            self._cancel_ta(why)
            return
        task = self.tasks[self.decision.switch_to or ""]
        assert task.plan is not None and self._robot_free()
        self.ta = self.roles.open(
            C1, COORDINATE, task.plan, conversation_id=f"{task.task_id}-exec{task.plan_index}"
        )
        resumed = task.state is TaskState.PREEMPTED
        self.ta_task = task.task_id
        self.ta_cancelled = False
        task.leaf = 0
        self._progress(task, TaskState.RUNNING, detail="resumed" if resumed else f"plan {task.plan.plan_id}")
        self.log.info("task %s: plan %s sent to a_ta", task.task_id, task.plan.plan_id)

    def _cancel_ta(self, why: str) -> None:
        """Cancel the plan a_ta runs (coordinate protocol): a_ta reports Terminating, then
        Preempted once the robot is safe."""
        if self.ta_cancelled or self.ta is None:
            return
        task = self.tasks.get(self.ta_task or "")
        plan_id = task.plan.plan_id if task is not None and task.plan is not None else ""
        self.ta.cancel(SWStatus(state=SWState.TERMINATING, plan_id=plan_id, reason=why))
        self.ta_cancelled = True
        if task is not None:
            self._progress(task, TaskState.TERMINATING, detail=why)
        self.log.info("cancel sent to a_ta: %s", why)

    # ---- restarts ----
    def setup(self) -> None:
        kept = self.kept.load()
        if kept is not None:
            self._restore(kept)

    def persist(self) -> None:
        now = self._kept_signature()
        if now != self._kept_as:  # encode and compare the whole queue only when it changed
            self._kept_as = now
            self.kept.save(self._kept())

    def _kept_signature(self) -> tuple[object, ...]:
        """What :meth:`_kept` depends on that can change, compared cheaply every step (a
        task's request, acceptance time, deadline and order never change)."""
        return (
            tuple(
                (
                    t.task_id,
                    t.state,
                    t.step,
                    t.leaf,
                    t.replans,
                    t.plan_index,
                    t.plan.plan_id if t.plan is not None else None,
                    t.cancel,
                    t.detail,
                )
                for t in self.tasks.values()
            ),
            self.ta_task,
            self.ta.conversation_id if self.ta is not None else None,
            self.ta_cancelled,
            self.subscription.conversation_id if self.subscription is not None else None,
            self.unsent_changes,
        )

    def _kept(self) -> KeptCoordinator:
        return KeptCoordinator(
            tasks=[
                KeptTask(
                    request=t.request.keep(),
                    accepted_at=t.accepted_at,
                    deadline=t.deadline,
                    order=t.order,
                    state=t.state,
                    plan=t.plan if t.task_id == self.ta_task else None,
                    plan_index=t.plan_index,
                    replans=t.replans,
                    step=t.step,
                    leaf=t.leaf,
                    cancel=encode(t.cancel.msg) if t.cancel is not None else None,
                    detail=t.detail,
                )
                for t in sorted(self.tasks.values(), key=lambda t: t.order)
            ],
            ta_task=self.ta_task,
            ta_conversation=self.ta.conversation_id if self.ta is not None else None,
            ta_cancelled=self.ta_cancelled,
            subscription=self.subscription.keep() if self.subscription is not None else None,
            unsent=list(self.unsent),
        )

    @staticmethod
    def _received(data: bytes) -> Received:
        msg = decode(data)
        content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
        return Received(msg, content, C2)

    def _restore(self, kept: KeptCoordinator) -> None:
        """Take back the commands of a previous a_co (see the module docstring)."""
        for k in kept.tasks:
            try:
                cancel = self._received(k.cancel) if k.cancel is not None else None
                state = "cancelling" if cancel is not None else "agreed"
                conv = self.roles.restore(C2, FIPA_REQUEST, state, kept=k.request, expect=HumanCommand)
            except (DecodeError, ContentError, RestoreError) as exc:
                self.log.warning("a kept command cannot be taken back (%s): dropped", exc)
                continue
            command = conv.opening_content(HumanCommand)
            on_ta = conv.conversation_id == kept.ta_task and kept.ta_conversation is not None
            task = Task(
                conv.conversation_id,
                command,
                conv,
                k.accepted_at,
                k.deadline,
                k.order,
                state=k.state if on_ta or k.state is TaskState.PREEMPTED else TaskState.WAITING,
                plan=k.plan if on_ta else None,
                plan_index=k.plan_index,
                replans=k.replans,
                needs_plan=not on_ta,
                step=k.step,
                leaf=k.leaf,
                cancel=cancel,
                detail=k.detail,
            )
            self.tasks[task.task_id] = task
        self._order = itertools.count(max((t.order for t in self.tasks.values()), default=-1) + 1)
        if kept.ta_task in self.tasks and kept.ta_conversation is not None:
            self.ta_task, self.ta_cancelled = kept.ta_task, kept.ta_cancelled
            self.ta = self.roles.restore(C1, COORDINATE, "running", conversation_id=kept.ta_conversation)
        if kept.subscription is not None:
            try:
                self.subscription = self.roles.restore(C2, FIPA_SUBSCRIBE, "active", kept=kept.subscription)
            except RestoreError as exc:
                self.log.warning("the kept progress subscription cannot be taken back (%s)", exc)
        for progress in kept.unsent:
            self._keep_unsent(progress)
        self.reschedule = True
        self.log.info(
            "restored %d command(s) from %s%s",
            len(self.tasks),
            self.kept.path,
            f"; a_ta runs {self.ta_task}" if self.ta_task else "",
        )

    def peer_changed(self, peer: str, alive: bool) -> None:
        if peer != "a_ta":
            return
        if not alive and self.ta_task is not None:
            self.ta_lost = True
            self.log.warning("a_ta disappeared while running %s; the robot holds position", self.ta_task)
        elif alive and self.ta_lost and self.ta is not None and self.ta.answered_last is not None:
            self.log.info("a_ta is back: the last confirm goes again (a new a_ta will not know it)")
            self.ta.answer_again()

    # ---- the person's commands (C2, fipa-request, participant) ----
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_command(self, conv: Conversation) -> None:
        assert conv.last is not None
        self.person.append(("command", conv, conv.last))

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.CANCEL)
    def _on_stop(self, conv: Conversation) -> None:
        """Answered once the robot is safe (see :meth:`_finish`)."""
        assert conv.last is not None
        self.person.append(("stop", conv, conv.last))

    # ---- the person's progress subscription (C2, fipa-subscribe, participant) ----
    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.SUBSCRIBE)
    def _on_subscribe(self, conv: Conversation) -> None:
        if not isinstance(conv.content, ProgressSubscription):
            conv.refuse_with(Performative.REFUSE, "I report the progress of commands only")
            return
        self.subscription = conv
        conv.reply(Performative.AGREE)
        if self.unsent:
            self.log.info("sending %d progress report(s) kept until a subscription", len(self.unsent))
        while self.unsent:
            conv.reply(Performative.INFORM, self.unsent.popleft())
            self.unsent_changes += 1

    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.CANCEL)
    def _on_unsubscribe(self, conv: Conversation) -> None:
        self._unsubscribe(conv)
        conv.reply(Performative.INFORM)

    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.NOT_UNDERSTOOD)
    def _on_progress_not_understood(self, conv: Conversation) -> None:
        """Never answered (FIPA SC00037 §3.12); it ends the conversation: a_hi did not
        understand the progress stream, so the subscription is over."""
        self._unsubscribe(conv)
        self.log.info("not-understood from a_hi (conversation %s) dropped", conv.conversation_id)

    def _unsubscribe(self, conv: Conversation) -> None:
        if self.subscription is not None and self.subscription.conversation_id == conv.conversation_id:
            self.subscription = None

    # ---- the person's questions (C2, fipa-query, participant) ----
    @handles(FIPA_QUERY, PARTICIPANT, Performative.QUERY_REF)
    def _on_status_query(self, conv: Conversation) -> None:
        if isinstance(conv.content, StatusQuery):
            conv.reply(Performative.INFORM_REF, self.status())
        else:
            conv.refuse_with(Performative.REFUSE, "I answer status queries only")

    @handles(FIPA_QUERY, PARTICIPANT, Performative.QUERY_IF)
    def _on_yes_no_query(self, conv: Conversation) -> None:
        conv.refuse_with(Performative.REFUSE, "I answer what I am doing (query-ref), not yes/no questions")

    def status(self) -> Status:
        """Every command a_co holds, the one on a_ta first, then by acceptance."""
        now = time.time()
        tasks = sorted(self.tasks.values(), key=lambda t: (t.task_id != self.ta_task, t.order))
        return Status(
            tasks=tuple(
                TaskStatus(
                    command_id=t.task_id,
                    text=t.command.text,
                    state=t.state,
                    step=t.step,
                    priority=t.command.priority,
                    deadline_in_s=round(t.deadline - now, 1) if t.deadline is not None else None,
                )
                for t in tasks
            )
        )

    # ---- plans from a_pl (C3, fipa-request, initiator) ----
    def _planned(self, conv: Conversation) -> Task | None:
        """The task whose outstanding plan request ``conv`` is (None: no longer wanted)."""
        for t in self.tasks.values():
            if t.planning is conv:
                t.planning = None
                return t
        if not conv.timed_out and not conv.not_understood:
            self.log.info("reply from a_pl to a plan request no longer wanted: dropped")
        return None

    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_plan(self, conv: Conversation) -> None:
        task = self._planned(conv)
        if task is None:
            return
        plan = conv.content
        if not isinstance(plan, HierarchicalPlan):
            self._finish(task, False, f"no plan: {conv.reason}")
            return
        task.plan = plan
        task.needs_plan = False
        self.reschedule = True
        if task.state is TaskState.PLANNING:
            self._progress(task, TaskState.WAITING, detail=f"plan #{task.plan_index} ready")
        self.log.info(
            "task %s: plan #%d received (%s, %.0f s expected, %d km queries)",
            task.task_id,
            task.plan_index,
            "complete" if plan.complete else "partial",
            plan.cost,
            plan.km_queries,
        )

    @handles(FIPA_REQUEST, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_no_plan(self, conv: Conversation) -> None:
        """Refused, failed, not understood, or unanswered by the reply-by deadline."""
        task = self._planned(conv)
        if task is not None:
            failure = conv.content
            reason = failure.reason if isinstance(failure, PlanFailure) else conv.reason
            self._finish(task, False, f"no plan: {reason}")

    # ---- a_ta's states (C1, coordinate, initiator) ----
    @handles(COORDINATE, INITIATOR, Performative.INFORM)
    def _on_ta_state(self, conv: Conversation) -> None:
        """Every L_SW inform is confirmed (paper §5.4), also one of a conversation a_co has
        left (a_ta waits for the confirm)."""
        conv.send(Performative.CONFIRM)
        task = self.tasks.get(self.ta_task or "")
        if conv is not self.ta or task is None or conv.last is None:
            return
        self.ta_lost = False  # a_ta speaks in the plan's conversation
        if isinstance(conv.content, SWStatus):
            self._sw_state(task, conv.content)

    @handles(COORDINATE, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_ta_failed(self, conv: Conversation) -> None:
        task = self.tasks.get(self.ta_task or "")
        if conv is not self.ta or task is None or conv.timed_out or conv.last is None:
            return
        self._release_ta()
        self._finish(task, False, f"a_ta {conv.last.performative.value}: {conv.reason}")

    @handles(COORDINATE, INITIATOR, Performative.NOT_UNDERSTOOD)
    def _on_ta_not_understood(self, conv: Conversation) -> None:
        task = self.tasks.get(self.ta_task or "")
        if conv is self.ta and task is not None and self.ta_lost:
            self.log.warning("a_ta came back without its plan: task %s is planned again", task.task_id)
            self.ta_lost = False
            self._sw_state(task, SWStatus(state=SWState.REPLAN, plan_id="", reason="a_ta restarted"))
            return
        self._on_ta_failed(conv)

    def _sw_state(self, task: Task, status: SWStatus) -> None:
        self.log.info("a_ta %s %s", status.state.value, status.step or status.reason or "")
        state = status.state
        if state is SWState.RUNNING:
            if status.step and task.plan is not None:
                task.leaf = next(
                    (i for i, (path, _) in enumerate(task.plan.root.leaves()) if path == status.step),
                    task.leaf,
                )
                self._progress(task, task.state, step=status.step)
            return
        if state is SWState.TERMINATING:
            self._progress(task, TaskState.TERMINATING, step=status.step, detail=status.reason or task.detail)
            return
        if state not in (SWState.SUCCEEDED, SWState.REPLAN, SWState.PREEMPTED, SWState.ERROR):
            return
        self._release_ta()
        self._world_changed(task)
        if task.cancel is not None:  # the person's stop: the robot is safe now
            if state is SWState.SUCCEEDED:
                self._finish(task, True, "the task had already succeeded", stopped=True)
            else:
                self._finish(task, False, f"stopped; {status.reason or 'the robot is safe'}", stopped=True)
        elif state is SWState.SUCCEEDED:
            self._finish(task, True, "the task succeeded")
        elif state is SWState.ERROR:
            self._finish(task, False, f"execution failed: {status.reason or 'unknown error'}")
        elif state is SWState.REPLAN:
            task.replans += 1
            task.plan, task.needs_plan = None, True
            self._progress(
                task, TaskState.PLANNING, detail=status.reason or "the world differs from the plan"
            )
        else:  # PREEMPTED
            task.plan, task.needs_plan = None, True
            self._progress(task, TaskState.PREEMPTED, detail=task.detail or "preempted")

    def _world_changed(self, ended: Task) -> None:
        """a_ta ended a plan: the world moved, so waiting plans were made for another world."""
        self.reschedule = True
        for t in self.tasks.values():
            if t is not ended and t.plan is not None and t.state not in _ON_TA:
                t.plan, t.needs_plan = None, True

    def _release_ta(self) -> None:
        self.ta_lost = False
        if self.ta is not None:
            self.ta.stop_waiting()
        self.ta_task = None
        self.ta = None
        self.ta_cancelled = False

    def _progress(self, task: Task, state: TaskState, *, step: str | None = None, detail: str = "") -> None:
        task.state = state
        if step is not None:
            task.step = step
        if self.rerun is not None:  # Rerun: the queue, when it changed
            self.rerun.queue(self.status())
        progress = Progress(command_id=task.task_id, state=state, step=task.step, detail=detail)
        if self.subscription is None:
            self._keep_unsent(progress)
        else:
            self.subscription.reply(Performative.INFORM, progress)

    def _keep_unsent(self, progress: Progress) -> None:
        """Keep ``progress`` for the next agreed subscription; past a bound (per command:
        ``PROGRESS_KEPT_PER_COMMAND``, in all: ``PROGRESS_KEPT``) the oldest report goes."""
        cid = progress.command_id
        if sum(p.command_id == cid for p in self.unsent) >= PROGRESS_KEPT_PER_COMMAND:
            oldest = next(i for i, p in enumerate(self.unsent) if p.command_id == cid)
            del self.unsent[oldest]
            self._dropped(cid)
        elif len(self.unsent) >= PROGRESS_KEPT:
            self._dropped(self.unsent.popleft().command_id)
        self.unsent.append(progress)
        self.unsent_changes += 1

    def _dropped(self, command_id: str) -> None:
        self.counters["progress_dropped"] += 1
        if self.counters["progress_dropped"] == 1:
            self.log.warning(
                "no progress subscription: the oldest kept report of %s dropped (at most %d per "
                "command, %d in all, are kept)",
                command_id,
                PROGRESS_KEPT_PER_COMMAND,
                PROGRESS_KEPT,
            )

    def _finish(self, task: Task, succeeded: bool, detail: str, *, stopped: bool = False) -> None:
        outcome = CommandOutcome(command_id=task.task_id, succeeded=succeeded, detail=detail)
        if stopped and task.cancel is not None:
            # FIPA cancel meta-protocol: the answer to the cancel ends the conversation
            perf = Performative.FAILURE if succeeded else Performative.INFORM
            task.request.reply(perf, outcome, to=task.cancel)
            self._progress(task, TaskState.SUCCEEDED if succeeded else TaskState.STOPPED, detail=detail)
        else:
            task.request.reply(Performative.INFORM if succeeded else Performative.FAILURE, outcome)
            self._progress(task, TaskState.SUCCEEDED if succeeded else TaskState.FAILED, detail=detail)
        self.log.info("task %s %s: %s", task.task_id, "succeeded" if succeeded else "failed", detail)
        if self.ta_task == task.task_id:
            self._release_ta()
        if task.planning is not None:
            task.planning.abandon()
        del self.tasks[task.task_id]
        if self.rerun is not None:  # Rerun: the queue without it
            self.rerun.queue(self.status())

    def close(self) -> None:
        """Close a_co's part of the run's Rerun recording (services/runtime/main.py calls it)."""
        if self.rerun is not None:
            self.rerun.close()
