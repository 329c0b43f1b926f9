"""a_co — the coordinator (paper §5.5, Table 3, Figure 11a; docs/agents.md, "a_co").

Its FSM (trigger, procReq, compSP, schedule, switch: each behaviour's ``doc`` in
:meth:`Coordinator.build_fsm`) takes a_hi's commands, has a_pl plan them and decides, after
TaskER (scheduling.py), which plan a_ta runs, switching by the coordinate protocol on C1 (a
``cancel`` makes a_ta put held objects down and report Preempted). a_ta's and a_pl's
communicates are handled in every state; each L_SW inform is confirmed (paper §5.4).

Towards the person (C2, L_HC): commands by fipa-request (agree, then inform or failure with a
CommandOutcome; a ``cancel`` is answered once the robot is safe), progress by fipa-subscribe
(a Progress inform at every change, served by the role: services/runtime/roles/served.py), status by
fipa-query.

Restarts (docs/recovery.md): the roles keep the commands (``keep=TaskNote``) and the progress
subscription, the runtime a_co's ``NOTE``; :meth:`Coordinator.on_restored`, then
:meth:`Coordinator.setup`, go on from them. When a_ta's token comes back after it disappeared
while a_ta ran a plan, a_co sends its last confirm again: the same a_ta drops the copy, a
restarted one answers not-understood, and the command is planned again.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import msgspec

from services.agents.coordinator.scheduling import Candidate, Decision, Running, decide, plan_left
from services.runtime.agent import FSM, RESEND_ON_RETURN, Agent, Arc, Behaviour, Received, Transport, once
from services.runtime.roles import INITIATOR, PARTICIPANT, Conversation, handles, initiator, participant
from services.spec.model import SystemSpec
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
from shared.fipa_codec import Performative, encode
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
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure
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


class TaskNote(msgspec.Struct, kw_only=True):
    """What a_co notes of a command: the data of its C2 conversation, which the role keeps
    across a restart (``keep=TaskNote``; docs/recovery.md). Times are POSIX s (``deadline``
    None: none); ``order`` the order of acceptance; ``leaf`` the index of the leaf a_ta runs;
    ``cancel`` the person's cancel, answered when the robot is safe, as an encoded
    communicate (FIPA SC00061 msgpack)."""

    accepted_at: float
    deadline: float | None
    order: int
    state: TaskState = TaskState.WAITING
    plan: HierarchicalPlan | None = None
    plan_index: int = 0
    replans: int = 0
    step: str | None = None
    leaf: int = 0
    cancel: bytes | None = None
    detail: str = ""


class CoordinatorNote(msgspec.Struct, kw_only=True):
    """What a_co keeps across a restart besides its conversations (its ``NOTE``): the task
    whose plan a_ta runs (or is terminating), its C1 conversation, whether a cancel was sent
    in it, and the progress made while no subscription was agreed, oldest first."""

    ta_task: str | None = None
    ta_conversation: str | None = None
    ta_cancelled: bool = False
    unsent: list[Progress] = msgspec.field(default_factory=list)


@dataclass
class Task:
    """A command being coordinated: ``task_id`` is the C2 conversation-id, ``request`` that
    conversation and ``note`` its data; ``planning`` the outstanding plan request to a_pl."""

    task_id: str
    command: HumanCommand
    request: Conversation
    note: TaskNote
    needs_plan: bool = True
    planning: Conversation | None = None


class Coordinator(Agent):
    name = "a_co"
    NOTE = CoordinatorNote
    note: CoordinatorNote
    ROLES = (
        # the commands and the progress subscription are kept across a restart (docs/recovery.md)
        participant(C2, FIPA_REQUEST, L_HC, keep=TaskNote),
        participant(C2, FIPA_SUBSCRIBE, L_HC, keep=True),
        participant(C2, FIPA_QUERY, L_HC),
        initiator(C3, FIPA_REQUEST, L_HFSM, reply_by_s=PLAN_REPLY_BY_S, retry_s=PLAN_RETRY_S),
        # a plan sent while a_ta (or the robot's router) is gone goes again when a_ta's token
        # reappears, until a_ta answers (docs/recovery.md, "Across two hosts")
        initiator(C1, COORDINATE, L_HFSM, L_SW, retry_s=RESEND_ON_RETURN),
    )

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
        """a_co's memory (paper §3.2: the agent's internal memory), then the runtime's
        (:class:`~services.runtime.agent.Agent`), which builds the FSM and gives the kept
        commands back (:meth:`on_restored`), then what needs the runtime: the progress stream
        and a viewer's queue."""
        self.ta_lost = False  # a_ta's token disappeared while it ran a plan
        self.tasks: dict[str, Task] = {}  # the commands held, by conversation-id
        self.ta: Conversation | None = None  # the C1 conversation of the plan a_ta runs
        self.person: deque[Callable[[], None]] = deque()  # the person's commands and stops, for procReq
        self.decision: Decision = Decision(None, False, "")  # schedule's, which switch carries out
        self.reschedule = False  # plans or a_ta's state changed: schedule again
        super().__init__(transport, spec)
        # a_hi's progress subscription: what is made while none is agreed is kept in the NOTE,
        # bounded, and sent after the next agree (services/runtime/roles/served.py); one kept
        # across a restart, taken back above, takes the stream
        self.progress = self.roles.serve(
            C2,
            FIPA_SUBSCRIBE,
            unsent=lambda: self.note.unsent,
            about=lambda progress: progress.command_id,
            kept_each=PROGRESS_KEPT_PER_COMMAND,
            kept_in_all=PROGRESS_KEPT,
            dropped="progress_dropped",
        )
        self.rerun = self.engine.hooks.queue(self.name) if self.engine.hooks else None  # a viewer

    def build_fsm(self) -> FSM:
        return FSM(
            [
                Behaviour(
                    "trigger",
                    self.handle_received,
                    terminal=self._has_work,
                    doc="idle: receive commands from a_hi and a_ta's states",
                ),
                once(
                    "procReq", self._proc_req, "store new commands (priority, deadline); stop cancelled ones"
                ),
                Behaviour(
                    "compSP",
                    self.handle_received,
                    terminal=self._plans_collected,
                    on_enter=self._request_plans,
                    doc="request plans of all waiting commands from a_pl; collect them",
                ),
                once(
                    "schedule",
                    self._schedule,
                    "decide from the plans' costs: continue, or switch the plan a_ta runs",
                ),
                once(
                    "switch",
                    self._switch,
                    "coordinate protocol on C1: cancel the running plan, or start the chosen one",
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
        return any(
            t.needs_plan and t.planning is None and t.note.state not in _ON_TA for t in self.tasks.values()
        )

    def _has_work(self) -> bool:
        return self._person_spoke() or self._plans_needed() or self.reschedule

    def _plans_collected(self) -> bool:
        return all(t.planning is None for t in self.tasks.values())

    # ---- behaviours ----
    def _proc_req(self) -> None:
        self.handle_received()
        while self.person:
            self.person.popleft()()

    def _accept(self, conv: Conversation, item: Received) -> None:
        if not isinstance(item.content, HumanCommand):
            conv.refuse_with(Performative.REFUSE, "no command in the request")
            return
        now = self.sources.time()
        task_id = conv.conversation_id or f"task-{len(self.tasks)}"
        if task_id in self.tasks:  # (the same request again is the role's: services/runtime/roles/)
            conv.refuse_with(Performative.REFUSE, f"command {task_id} is already being carried out")
            return
        deadline = now + item.content.deadline_s if item.content.deadline_s is not None else None
        order = max((t.note.order for t in self.tasks.values()), default=-1) + 1  # after every one held
        conv.data = TaskNote(accepted_at=now, deadline=deadline, order=order)
        task = Task(task_id, item.content, conv, conv.data)
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
        task.note.cancel = encode(cancel.msg)
        if task.task_id == self.note.ta_task:
            self._cancel_ta(f"stopped by the person: {task.command.text}")
            return
        self._drop_planning(task)
        self._finish(task, False, "stopped; the robot was not working on it", stopped=True)

    def _request_plans(self) -> None:
        for task in list(self.tasks.values()):
            if not (task.needs_plan and task.planning is None and task.note.state not in _ON_TA):
                continue
            if task.note.replans > MAX_REPLANS_PER_TASK:
                self._finish(task, False, f"no progress after {task.note.replans} replans")
                continue
            task.note.plan_index += 1
            gtn = GroundTaskNetwork(
                task_id=task.task_id, tasks=(task.command.goal,), plan_index=task.note.plan_index
            )
            task.planning = self.roles.open(
                C3, FIPA_REQUEST, gtn, conversation_id=f"{task.task_id}-plan{task.note.plan_index}"
            )
            if task.note.state is not TaskState.PREEMPTED:
                self._progress(task, TaskState.PLANNING, detail=f"plan #{task.note.plan_index} requested")
            self.log.info("task %s: requested plan #%d", task.task_id, task.note.plan_index)

    def _schedule(self) -> None:
        self.handle_received()
        self.reschedule = False
        now = self.sources.time()
        waiting = [
            self._candidate(t, now, t.note.plan.cost)
            for t in self.tasks.values()
            if t.note.plan is not None and t.note.state not in _ON_TA
        ]
        running: Running | None = None
        if self.note.ta_task is not None:
            if self.note.ta_cancelled:  # a_ta is on its way to a safe state: wait for Preempted
                self.decision = Decision(None, False, "a_ta is terminating")
                return
            r = self.tasks.get(self.note.ta_task)
            if r is not None and r.note.plan is not None:
                remaining, stop = plan_left(r.note.plan, r.note.leaf)
                running = Running(self._candidate(r, now, remaining), remaining, stop)
        self.decision = decide(running, waiting)
        if self.decision.switch_to is not None:
            self.log.info("schedule: %s", self.decision.reason)

    def _candidate(self, task: Task, now: float, duration: float) -> Candidate:
        left = task.note.deadline - now if task.note.deadline is not None else None
        return Candidate(task.task_id, task.command.priority, duration, left, task.note.order)

    def _switch(self) -> None:
        if self.decision.preempt:
            running = self.tasks.get(self.note.ta_task or "")
            chosen = self.tasks.get(self.decision.switch_to or "")
            why = f"preempted for “{chosen.command.text}”" if chosen else "preempted"
            if running is not None:
                running.note.detail = why
            self._cancel_ta(why)
            return
        task = self.tasks[self.decision.switch_to or ""]
        assert task.note.plan is not None and self.note.ta_task is None  # the robot is free
        self.ta = self.roles.open(
            C1, COORDINATE, task.note.plan, conversation_id=f"{task.task_id}-exec{task.note.plan_index}"
        )
        resumed = task.note.state is TaskState.PREEMPTED
        self.note.ta_task, self.note.ta_conversation = task.task_id, self.ta.conversation_id
        self.note.ta_cancelled = False
        task.note.leaf = 0
        self._progress(
            task, TaskState.RUNNING, detail="resumed" if resumed else f"plan {task.note.plan.plan_id}"
        )
        self.log.info("task %s: plan %s sent to a_ta", task.task_id, task.note.plan.plan_id)

    def _cancel_ta(self, why: str) -> None:
        """Cancel the plan a_ta runs (coordinate protocol): a_ta reports Terminating, then
        Preempted once the robot is safe."""
        if self.note.ta_cancelled or self.ta is None:
            return
        task = self.tasks.get(self.note.ta_task or "")
        plan_id = task.note.plan.plan_id if task is not None and task.note.plan is not None else ""
        self.ta.cancel(SWStatus(state=SWState.TERMINATING, plan_id=plan_id, reason=why))
        self.note.ta_cancelled = True
        if task is not None:
            self._progress(task, TaskState.TERMINATING, detail=why)
        self.log.info("cancel sent to a_ta: %s", why)

    # ---- restarts (the roles keep the conversations: docs/recovery.md) ----
    def on_restored(self, conversation: Conversation) -> None:
        """A command, or a_hi's progress subscription, of a previous a_co: a command waits for
        a plan again unless a_ta runs its plan, and its cancel, if any, for the robot to be safe.
        Raises ValueError (RestoreError) for a kept cancel that does not decode."""
        note = conversation.data
        if not isinstance(note, TaskNote):  # the progress subscription: the role's (self.progress)
            return
        cid = conversation.conversation_id
        on_ta = cid == self.note.ta_task and self.note.ta_conversation is not None
        if not on_ta:
            note.plan = None
            note.state = note.state if note.state is TaskState.PREEMPTED else TaskState.WAITING
        command = conversation.opening_content(HumanCommand)
        self.tasks[cid] = Task(cid, command, conversation, note, needs_plan=not on_ta)

    def setup(self) -> None:
        """Go on from what a previous a_co kept (:meth:`on_restored` took its commands back):
        the plan a_ta runs in its C1 conversation, and plan again what was being planned."""
        note = self.note
        if note.ta_task in self.tasks and note.ta_conversation is not None:
            self.ta = self.roles.restore(C1, COORDINATE, "running", conversation_id=note.ta_conversation)
        else:
            note.ta_task, note.ta_conversation, note.ta_cancelled = None, None, False
        if self.tasks:
            self.reschedule = True
            running = f"; a_ta runs {note.ta_task}" if note.ta_task else ""
            self.log.info("restored %d command(s)%s", len(self.tasks), running)

    def peer_changed(self, peer: str, alive: bool) -> None:
        if peer != "a_ta":
            return
        if not alive and self.note.ta_task is not None:
            self.ta_lost = True
            self.log.warning("a_ta disappeared while running %s; the robot holds position", self.note.ta_task)
        elif alive and self.ta_lost and self.ta is not None and self.ta.replied_to is not None:
            self.log.info("a_ta is back: the last confirm goes again (a new a_ta will not know it)")
            self.ta.answer_again()

    # ---- the person's commands (C2, fipa-request, participant) ----
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_command(self, conv: Conversation) -> None:
        assert conv.last is not None
        self.person.append(partial(self._accept, conv, conv.last))

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.CANCEL)
    def _on_stop(self, conv: Conversation) -> None:
        """Answered once the robot is safe (:meth:`_finish`); its plan, if being made, withdrawn at once."""
        assert conv.last is not None
        task = self.tasks.get(conv.conversation_id)
        if task is not None:
            self._drop_planning(task)
        self.person.append(partial(self._stop_command, conv, conv.last))

    # ---- the person's progress subscription (C2, fipa-subscribe, participant; the role serves it) ----
    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.SUBSCRIBE)
    def _on_subscribe(self, conv: Conversation) -> None:
        if isinstance(conv.content, ProgressSubscription):
            self.progress.agree(conv)
        else:
            conv.refuse_with(Performative.REFUSE, "I report the progress of commands only")

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
        now = self.sources.time()
        tasks = sorted(self.tasks.values(), key=lambda t: (t.task_id != self.note.ta_task, t.note.order))
        return Status(
            tasks=tuple(
                TaskStatus(
                    command_id=t.task_id,
                    text=t.command.text,
                    state=t.note.state,
                    step=t.note.step,
                    priority=t.command.priority,
                    deadline_in_s=round(t.note.deadline - now, 1) if t.note.deadline is not None else None,
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

    def _drop_planning(self, task: Task) -> None:
        """The plan requested for ``task`` is no longer wanted: withdrawn (a_pl stops planning it)."""
        if task.planning is not None:
            task.planning.cancel_if_open()
        task.planning = None

    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_plan(self, conv: Conversation) -> None:
        task = self._planned(conv)
        if task is None:
            return
        plan = conv.content
        if not isinstance(plan, HierarchicalPlan):
            self._finish(task, False, f"no plan: {conv.reason}")
            return
        task.note.plan = plan
        task.needs_plan = False
        self.reschedule = True
        if task.note.state is TaskState.PLANNING:
            self._progress(task, TaskState.WAITING, detail=f"plan #{task.note.plan_index} ready")
        self.log.info(
            "task %s: plan #%d received (%s, %.0f s expected, %d km queries)",
            task.task_id,
            task.note.plan_index,
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
        task = self.tasks.get(self.note.ta_task or "")
        if conv is not self.ta or task is None or conv.last is None:
            return
        self.ta_lost = False  # a_ta speaks in the plan's conversation
        if isinstance(conv.content, SWStatus):
            self._sw_state(task, conv.content)

    @handles(COORDINATE, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_ta_failed(self, conv: Conversation) -> None:
        task = self.tasks.get(self.note.ta_task or "")
        if conv is not self.ta or task is None or conv.timed_out or conv.last is None:
            return
        self._release_ta()
        said = "sent a state a_co could not read" if conv.unreadable else conv.last.performative.value
        self._finish(task, False, f"a_ta {said}: {conv.reason}")

    @handles(COORDINATE, INITIATOR, Performative.NOT_UNDERSTOOD)
    def _on_ta_not_understood(self, conv: Conversation) -> None:
        task = self.tasks.get(self.note.ta_task or "")
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
            if status.step and task.note.plan is not None:
                task.note.leaf = next(
                    (i for i, (path, _) in enumerate(task.note.plan.root.leaves()) if path == status.step),
                    task.note.leaf,
                )
                self._progress(task, task.note.state, step=status.step)
            return
        if state is SWState.TERMINATING:
            self._progress(
                task, TaskState.TERMINATING, step=status.step, detail=status.reason or task.note.detail
            )
            return
        if state not in (SWState.SUCCEEDED, SWState.REPLAN, SWState.PREEMPTED, SWState.ERROR):
            return
        self._release_ta()
        self._world_changed(task)
        if task.note.cancel is not None:  # the person's stop: the robot is safe now
            if state is SWState.SUCCEEDED:
                self._finish(task, True, "the task had already succeeded", stopped=True)
            else:
                self._finish(task, False, f"stopped; {status.reason or 'the robot is safe'}", stopped=True)
        elif state is SWState.SUCCEEDED:
            # a_ta's reason says how the world was judged (the content check's count)
            self._finish(task, True, status.reason or "the task succeeded")
        elif state is SWState.ERROR:
            self._finish(task, False, f"execution failed: {status.reason or 'unknown error'}")
        elif state is SWState.REPLAN:
            task.note.replans += 1
            task.note.plan, task.needs_plan = None, True
            self._progress(
                task, TaskState.PLANNING, detail=status.reason or "the world differs from the plan"
            )
        else:  # PREEMPTED
            task.note.plan, task.needs_plan = None, True
            self._progress(task, TaskState.PREEMPTED, detail=task.note.detail or "preempted")

    def _world_changed(self, ended: Task) -> None:
        """a_ta ended a plan: the world moved, so waiting plans were made for another world."""
        self.reschedule = True
        for t in self.tasks.values():
            if t is not ended and t.note.plan is not None and t.note.state not in _ON_TA:
                t.note.plan, t.needs_plan = None, True

    def _release_ta(self) -> None:
        self.ta_lost = False
        if self.ta is not None:
            self.ta.stop_awaiting_replies()
        self.note.ta_task, self.note.ta_conversation = None, None
        self.ta = None
        self.note.ta_cancelled = False

    def _progress(self, task: Task, state: TaskState, *, step: str | None = None, detail: str = "") -> None:
        task.note.state = state
        if step is not None:
            task.note.step = step
        if self.rerun is not None:  # Rerun: the queue, when it changed
            self.rerun.queue(self.status())
        self.progress.inform(
            Progress(command_id=task.task_id, state=state, step=task.note.step, detail=detail)
        )

    def _finish(self, task: Task, succeeded: bool, detail: str, *, stopped: bool = False) -> None:
        outcome = CommandOutcome(command_id=task.task_id, succeeded=succeeded, detail=detail)
        if stopped and task.note.cancel is not None:  # answer the person's cancel: it ends the conversation
            task.request.answer_cancel(not succeeded, outcome, to=task.request.decode(task.note.cancel))
            self._progress(task, TaskState.SUCCEEDED if succeeded else TaskState.STOPPED, detail=detail)
        else:
            task.request.reply(Performative.INFORM if succeeded else Performative.FAILURE, outcome)
            self._progress(task, TaskState.SUCCEEDED if succeeded else TaskState.FAILED, detail=detail)
        self.log.info("task %s %s: %s", task.task_id, "succeeded" if succeeded else "failed", detail)
        if self.note.ta_task == task.task_id:
            self._release_ta()
        self._drop_planning(task)
        del self.tasks[task.task_id]
        if self.rerun is not None:  # Rerun: the queue without it
            self.rerun.queue(self.status())

    def close(self) -> None:
        """Close a_co's part of the run's Rerun recording (services/runtime/main.py calls it)."""
        if self.rerun is not None:
            self.rerun.close()
