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

Restarts (docs/recovery.md): the roles keep every accepted command (``keep=TaskNote``: its
conversation with what a_co notes of it) and the progress subscription, and the runtime keeps
a_co's ``NOTE`` (the plan a_ta runs, the progress not yet sent), in a_co's state file
(services/runtime/state_store.py) after the step that changed them; a restarted a_co gets them
back (:meth:`Coordinator.on_restored`, then :meth:`Coordinator.setup`) and plans again what
was being planned. A copy of a command it
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
    handles,
    initiator,
    participant,
)
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
from shared.fipa_codec import Performative, decode, encode
from shared.fipa_codec.languages import decode_content
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
    conversation and ``note`` its data; ``planning`` the outstanding plan request to a_pl;
    ``cancel`` the person's cancel (noted encoded in ``note``)."""

    task_id: str
    command: HumanCommand
    request: Conversation
    note: TaskNote
    needs_plan: bool = True
    planning: Conversation | None = None
    cancel: Received | None = None


PersonSaid = tuple[Literal["command", "stop"], Conversation, Received]
"""What the person said, for procReq: a command (its request) or a stop (its cancel)."""


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

    def build_fsm(self) -> FSM:
        self.ta_lost = False  # a_ta's token disappeared while it ran a plan
        self.tasks: dict[str, Task] = {}
        self.ta: Conversation | None = None  # the C1 conversation of the plan a_ta runs
        self.person: deque[PersonSaid] = deque()  # commands and stops for procReq
        self.subscription: Conversation | None = None  # a_hi's progress subscription
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
        return any(
            t.needs_plan and t.planning is None and t.note.state not in _ON_TA for t in self.tasks.values()
        )

    def _robot_free(self) -> bool:
        return self.note.ta_task is None

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
        now = self.sources.time()
        task_id = conv.conversation_id or f"task-{len(self.tasks)}"
        if task_id in self.tasks:  # (the same request again is the role's: services/runtime/roles.py)
            conv.refuse_with(Performative.REFUSE, f"command {task_id} is already being carried out")
            return
        deadline = now + item.content.deadline_s if item.content.deadline_s is not None else None
        conv.data = TaskNote(accepted_at=now, deadline=deadline, order=next(self._order))
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
        task.cancel, task.note.cancel = cancel, encode(cancel.msg)
        if task.task_id == self.note.ta_task:
            self._cancel_ta(f"stopped by the person: {task.command.text}")
            return
        if task.planning is not None:
            task.planning.abandon()
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

    def _comp_sp_step(self) -> None:
        self.handle_received()

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
                leaves = r.note.plan.root.leaves()
                remaining = sum(n.duration for _, n in leaves[r.note.leaf :])
                running = Running(
                    self._candidate(r, now, remaining), remaining, self._interruption(r, leaves)
                )
        self.decision = decide(running, waiting)
        if self.decision.switch_to is not None:
            self.decisions.append(self.decision)
            self.log.info("schedule: %s", self.decision.reason)

    def _candidate(self, task: Task, now: float, duration: float) -> Candidate:
        left = task.note.deadline - now if task.note.deadline is not None else None
        return Candidate(task.task_id, task.command.priority, duration, left, task.note.order)

    @staticmethod
    def _interruption(task: Task, leaves: list[tuple[str, PlanNode]]) -> float:
        """Expected time (s) of the safe stop a_ta would run if cancelled now."""
        assert task.note.plan is not None
        for _, node in leaves[task.note.leaf :]:
            if node.on_cancel is not None:
                stop = task.note.plan.safe_stops.get(node.on_cancel)
                return sum(n.duration for _, n in stop.leaves()) if stop is not None else 0.0
            return 0.0
        return 0.0

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
        assert task.note.plan is not None and self._robot_free()
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
        Raises ValueError (DecodeError) for a kept cancel that does not decode."""
        note = conversation.data
        if not isinstance(note, TaskNote):  # the progress subscription (keep=True: no data)
            self.subscription = conversation
            return
        cid = conversation.conversation_id
        on_ta = cid == self.note.ta_task and self.note.ta_conversation is not None
        cancel = None
        if note.cancel is not None:
            msg = decode(note.cancel)
            content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
            cancel = Received(msg, content, C2)
        if not on_ta:
            note.plan = None
            note.state = note.state if note.state is TaskState.PREEMPTED else TaskState.WAITING
        command = conversation.opening_content(HumanCommand)
        self.tasks[cid] = Task(cid, command, conversation, note, needs_plan=not on_ta, cancel=cancel)

    def setup(self) -> None:
        """Go on from what a previous a_co kept (:meth:`on_restored` took its commands back):
        the plan a_ta runs in its C1 conversation, and plan again what was being planned."""
        note = self.note
        self._order = itertools.count(max((t.note.order for t in self.tasks.values()), default=-1) + 1)
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
        if self.note.unsent:
            self.log.info("sending %d progress report(s) kept until a subscription", len(self.note.unsent))
        while self.note.unsent:
            conv.reply(Performative.INFORM, self.note.unsent.pop(0))

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
        self._finish(task, False, f"a_ta {conv.last.performative.value}: {conv.reason}")

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
            self.ta.stop_waiting()
        self.note.ta_task, self.note.ta_conversation = None, None
        self.ta = None
        self.note.ta_cancelled = False

    def _progress(self, task: Task, state: TaskState, *, step: str | None = None, detail: str = "") -> None:
        task.note.state = state
        if step is not None:
            task.note.step = step
        if self.rerun is not None:  # Rerun: the queue, when it changed
            self.rerun.queue(self.status())
        progress = Progress(command_id=task.task_id, state=state, step=task.note.step, detail=detail)
        if self.subscription is None:
            self._keep_unsent(progress)
        else:
            self.subscription.reply(Performative.INFORM, progress)

    def _keep_unsent(self, progress: Progress) -> None:
        """Keep ``progress`` for the next agreed subscription; past a bound (per command:
        ``PROGRESS_KEPT_PER_COMMAND``, in all: ``PROGRESS_KEPT``) the oldest report goes."""
        cid = progress.command_id
        if sum(p.command_id == cid for p in self.note.unsent) >= PROGRESS_KEPT_PER_COMMAND:
            oldest = next(i for i, p in enumerate(self.note.unsent) if p.command_id == cid)
            del self.note.unsent[oldest]
            self._dropped(cid)
        elif len(self.note.unsent) >= PROGRESS_KEPT:
            self._dropped(self.note.unsent.pop(0).command_id)
        self.note.unsent.append(progress)

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
        if self.note.ta_task == task.task_id:
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
