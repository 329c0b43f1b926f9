"""a_pl — the planner (paper §5.5, Table 4, Figure 11b).

FSM states: idle (await a planning problem from a_co, fipa-request on C3), initialize (query
a_km for the knowledge the problem needs: fipa-query on C4, several conversations at once;
what the scene answer reveals — objects already held — is asked about next), search (HTN
search with GTPyhop, and the safe stop of every step), finalize (ask a_km whether the plan's
steps can run and achieve its goal in a hypothetical state of the knowledge base, paper
§5.7; then inform a_co of the L_HFSM hierarchical plan, or answer failure with a reason a person can
read).
"""

from __future__ import annotations

from collections import deque

import msgspec

from services.agents.planner.domain import ATOMIC_STATES, PlanActions, PlanningFailure, plan_task
from services.agents.planner.goals import goal_query, steps
from services.agents.planner.hfsm import to_hfsm
from services.agents.planner.knowledge import ARMS, Knowledge
from services.runtime.agent import FSM, Agent, Arc, Behaviour, Transport
from services.runtime.roles import INITIATOR, PARTICIPANT, Conversation, handles, initiator, participant
from services.spec.model import SystemSpec
from services.spec.names import C3, C4, FIPA_QUERY, FIPA_REQUEST, L_HFSM, L_WM
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspQuery,
    HypotheticalQuery,
    ObjectQuery,
    PlacementQuery,
    PourQuery,
    SceneQuery,
    SparqlQuery,
)

QUERY_REPLY_BY_S = 30.0
QUERY_RETRY_S = 2.0
"""Retransmission period of an unanswered a_km query (a_km may be restarting)."""
NO_GOAL = SparqlQuery("ASK { }")
"""The goal of a plan that states none (its steps are still checked): always true."""
FURNITURE = ("table", "cabinet")
"""Where objects can be put: a_pl asks a_km for placements on each."""


class Planner(Agent):
    name = "a_pl"
    ROLES = (
        participant(C3, FIPA_REQUEST, L_HFSM),
        initiator(C4, FIPA_QUERY, L_WM, reply_by_s=QUERY_REPLY_BY_S, retry_s=QUERY_RETRY_S),
    )

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
        """a_pl's memory (paper §3.2: the agent's internal memory), then the runtime's
        (:class:`~services.runtime.agent.Agent`), which builds the FSM."""
        self.requests: deque[Conversation] = deque()  # planning requests not yet taken up
        self.request: Conversation | None = None  # the planning request being worked on
        self.problem: GroundTaskNetwork | None = None  # its ground task network
        self.knowledge = Knowledge()  # what a_km answered for it
        self.pending: set[Conversation] = set()  # open knowledge queries; data = (kind, key)
        self.failure: str | None = None  # why it has no plan, in words (None: none yet)
        self.result: PlanActions | None = None  # the search's actions
        self.cancelled = False  # a_co cancelled it (and the cancel was answered)
        self.plan: HierarchicalPlan | None = None  # the search's plan as an L_HFSM hierarchy
        self.check: Conversation | None = None  # the hypothetical-state query
        self.checked = True  # a_km answered the hypothetical-state query (or none was asked)
        self.asked: set[tuple[str, tuple[str, ...]]] = set()  # (kind, key) of the queries asked for it
        self.started = 0.0  # when it was taken up (the agent's monotonic s)
        super().__init__(transport, spec)

    def build_fsm(self) -> FSM:
        return FSM(
            [
                Behaviour(
                    "idle",
                    self._idle,
                    terminal=lambda: self.request is not None,
                    doc="await a planning problem from a_co",
                ),
                Behaviour(
                    "initialize",
                    self.handle_received,
                    terminal=lambda: not self.pending or self.failure is not None,
                    on_enter=self._ask,
                    doc="query a_km for the knowledge the problem needs",
                ),
                Behaviour(
                    "search",
                    self._search,
                    terminal=lambda: True,
                    waits=False,
                    doc="HTN search for a plan (GTPyhop)",
                ),
                Behaviour(
                    "finalize",
                    self._finalize,
                    terminal=lambda: self.request is None,
                    on_enter=self._verify,
                    doc="check the plan's steps and goal in a hypothetical state (a_km); reply to a_co",
                ),
            ],
            arcs=[
                Arc("idle", "initialize"),
                Arc("initialize", "search", lambda: self.failure is None, "knowledge complete"),
                Arc("initialize", "finalize", lambda: self.failure is not None, "knowledge missing"),
                Arc("search", "finalize"),
                Arc("finalize", "idle"),
            ],
        )

    # ---- planning requests from a_co (fipa-request, participant) --------------------------
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_request(self, conv: Conversation) -> None:
        self.requests.append(conv)

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.CANCEL)
    def _on_cancel(self, conv: Conversation) -> None:
        """a_co's cancel of a plan request (FIPA cancel meta-protocol): the current or a waiting
        one is dropped and the cancel answered ``inform``; the current one's open knowledge
        queries are cancelled in turn (:meth:`_cancel_queries`)."""
        if conv is self.request:
            self.cancelled = True
            self.failure = "cancelled"
        elif conv in self.requests:
            self.requests.remove(conv)
        else:
            conv.refuse_with(Performative.FAILURE, "no such planning request (it has been answered)")
            return
        conv.reply(Performative.INFORM)
        self.log.info("planning cancelled by a_co")

    # ---- knowledge from a_km (fipa-query, initiator) ---------------------------------------
    @handles(FIPA_QUERY, INITIATOR, Performative.INFORM_REF, Performative.INFORM)
    def _on_answer(self, conv: Conversation) -> None:
        if conv is self.check:
            self._checked(conv)
        elif conv in self.pending:
            self.pending.discard(conv)
            if isinstance(conv.content, Answer):
                kind, key = conv.data
                self._learn(kind, key, conv.content)
            else:
                self._unanswered(conv)

    @handles(FIPA_QUERY, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_no_answer(self, conv: Conversation) -> None:
        """Refused, failed, not understood, or no answer by the reply-by deadline."""
        if conv is self.check:
            self._not_checked(conv)
        elif conv in self.pending:
            self.pending.discard(conv)
            self._unanswered(conv)

    def _unanswered(self, conv: Conversation) -> None:
        kind, key = conv.data
        if kind == "object" and not key[0].endswith("_gripper"):
            self.failure = f"I know of no {key[0]} ({conv.reason})"

    def _checked(self, conv: Conversation) -> None:
        """a_km's answer to the hypothetical query: the goal holds (the plan is sent) or not."""
        self.checked = True
        if not isinstance(conv.content, Answer) or conv.content.boolean is not True:
            self.failure = "the plan would not reach its goal in a_km's hypothetical state (it is false)"

    def _not_checked(self, conv: Conversation) -> None:
        """a_km answered the hypothetical query ``failure`` or ``refuse`` — a step cannot run
        ("step 7 pour(jar, cup): the cup cannot take …") — or not at all: the plan is not sent."""
        self.checked = True
        if conv.timed_out:
            self.failure = f"the plan could not be checked in a_km's hypothetical state ({conv.explanation})"
        else:
            self.failure = f"the plan cannot work: {conv.explanation}"

    # ---- the behaviours ---------------------------------------------------------------------
    def _idle(self) -> None:
        self.handle_received()
        if not self.requests:
            return
        conv = self.requests.popleft()
        problem = conv.content
        if not isinstance(problem, GroundTaskNetwork):
            conv.reply(Performative.REFUSE, PlanFailure(task_id="", reason="no ground task network"))
            return
        self.request, self.problem = conv, problem
        self.knowledge, self.failure, self.result, self.plan = Knowledge(), None, None, None
        self.cancelled = False
        self.asked = set()
        self.started = self.sources.monotonic()
        self.log.info(
            "planning #%d for %s: %s",
            problem.plan_index,
            problem.task_id,
            [(t.name, t.args) for t in problem.tasks],
        )

    def _query(self, kind: str, key: tuple[str, ...], query: msgspec.Struct) -> None:
        if (kind, key) in self.asked:
            return
        self.asked.add((kind, key))
        conv = self.roles.open(C4, FIPA_QUERY, query, performative=Performative.QUERY_REF, data=(kind, key))
        self.pending.add(conv)
        self.knowledge.queries += 1

    def _ask(self) -> None:
        """Open the knowledge queries this problem needs (paper Table 4: multiple initiations
        of the query protocol)."""
        assert self.problem is not None
        objects: list[str] = []
        for t in self.problem.tasks:
            objects.extend(a for a in t.args if a not in objects)
        self._query("scene", (), SceneQuery())
        for arm in ARMS:
            self._query("object", (f"{arm}_gripper",), ObjectQuery(f"{arm}_gripper"))
        for obj in objects:
            self._query("object", (obj,), ObjectQuery(obj))
            if obj not in FURNITURE:
                self._ask_movable(obj)
        for t in self.problem.tasks:
            if t.name == "pour" and len(t.args) == 2:
                self._query("pour", t.args, PourQuery(source=t.args[0], target=t.args[1]))

    def _ask_movable(self, obj: str) -> None:
        """Grasps of ``obj`` for each hand and its places on each piece of furniture."""
        for arm in ARMS:
            self._query("grasps", (obj, arm), GraspQuery(object=obj, arm=arm))
        for furniture in FURNITURE:
            self._query("placement", (obj, furniture), PlacementQuery(object=obj, surface=furniture))

    def _learn(self, kind: str, key: tuple[str, ...], answer: Answer) -> None:
        k = self.knowledge
        if kind in ("object", "scene"):
            for info in answer.objects:
                k.objects[info.name] = info
                if info.held_by:  # the safe stop must know how to put it down
                    self._ask_movable(info.name)
        elif kind == "grasps":
            k.grasps[(key[0], key[1])] = answer.grasps
        elif kind == "placement" and answer.placement is not None:
            k.placements[(key[0], key[1])] = answer.placement
        elif kind == "pour":
            k.pours[(key[0], key[1])] = answer.pour

    def _search(self) -> None:
        assert self.problem is not None
        if len(self.problem.tasks) != 1:
            self.failure = "I plan one task at a time"
            return
        t = self.problem.tasks[0]
        try:
            self.result = plan_task(self.knowledge, (t.name, *t.args), f"{t.name}({','.join(t.args)})")
            self.plan = self._hierarchical_plan(self.result)
        except PlanningFailure as exc:
            self.failure = str(exc)
        except Exception as exc:  # a bug in the domain must not take a_pl down
            self.log.exception("planner error")
            self.failure = f"planner error: {exc}"

    def _hierarchical_plan(self, result: PlanActions) -> HierarchicalPlan:
        assert self.problem is not None
        root, complete, cost = to_hfsm(result.actions, on_cancel=result.on_cancel, atomic=ATOMIC_STATES)
        stops = {key: to_hfsm(acts, atomic=ATOMIC_STATES)[0] for key, acts in result.safe_stops.items()}
        return HierarchicalPlan(
            plan_id=f"{self.problem.task_id}-p{self.problem.plan_index}",
            task_id=self.problem.task_id,
            root=root,
            complete=complete,
            cost=cost,
            km_queries=self.knowledge.queries,
            safe_stops=stops,
        )

    def _verify(self) -> None:
        """Ask a_km whether the plan's steps can run and the goal holds after them (hypothetical
        state)."""
        self.check, self.checked = None, True
        if self.failure is not None or self.result is None or self.plan is None:
            return
        query = goal_query(
            self.result.task, self.result.args, self.result.actions, self.plan.complete, self.knowledge
        )
        checked = steps(self.result.actions)
        if query is None and not checked:
            return  # the plan only senses: nothing to check
        self.check = self.roles.open(
            C4,
            FIPA_QUERY,
            HypotheticalQuery(steps=checked, query=query or NO_GOAL),
            performative=Performative.QUERY_REF,
        )
        self.checked = False
        self.knowledge.queries += 1

    def _finalize(self) -> None:
        assert self.problem is not None
        self.handle_received()
        request = self.request
        assert request is not None
        if self.cancelled:  # the cancel was answered: the request's conversation has ended
            self._cancel_queries()
            self._done()
            return
        if not self.checked:
            return
        elapsed = self.sources.monotonic() - self.started
        if self.failure is not None or self.plan is None:
            reason = self.failure or "no plan"
            request.reply(Performative.FAILURE, PlanFailure(task_id=self.problem.task_id, reason=reason))
            self.log.info("no plan: %s", reason)
        else:
            plan = msgspec.structs.replace(
                self.plan, km_queries=self.knowledge.queries, planning_time_s=round(elapsed, 3)
            )
            request.reply(Performative.INFORM, plan)
            self.log.info(
                "plan %s: %d leaves, %d safe stops, %s, %.1f s expected, %d queries, %.3f s",
                plan.plan_id,
                len(plan.root.leaves()),
                len(plan.safe_stops),
                "complete" if plan.complete else "partial",
                plan.cost,
                plan.km_queries,
                elapsed,
            )
        self._done()

    def _cancel_queries(self) -> None:
        """a_co cancelled the planning: the knowledge queries still open are cancelled too
        (FIPA SC00027 §2, the cancel meta-protocol), neither sent again nor awaited; a_km's
        answer that crossed a cancel, and its answer to the cancel, are taken and ignored."""
        for conv in [*self.pending, *([self.check] if self.check is not None else [])]:
            conv.cancel_if_open(forget=False)

    def _done(self) -> None:
        self.request = self.problem = None
        self.pending.clear()
        self.check, self.checked = None, True
