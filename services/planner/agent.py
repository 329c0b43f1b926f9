"""a_pl — the planner (paper §5.5, Table 4, Figure 11b).

FSM states: idle (await a planning problem from a_co, fipa-request on C3), initialize (query
a_km for the knowledge the problem needs: fipa-query on C4, several conversations at once),
search (HTN search with GTPyhop), finalize (turn the plan into an L_HFSM hierarchical plan and
inform a_co, or answer failure with a reason a person can read).
"""

from __future__ import annotations

import time

import msgspec

from services.planner.domain import PlanningFailure, find_plan
from services.planner.hfsm import to_hfsm
from services.planner.knowledge import ARMS, Knowledge
from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Arc, Behaviour
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanFailure
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspQuery,
    ObjectQuery,
    PlacementQuery,
    PourQuery,
    SceneQuery,
)

QUERY_REPLY_BY_S = 30.0
SURFACE = "table"


class Planner(Agent):
    name = "a_pl"

    def build_fsm(self) -> FSM:
        self.request: Received | None = None
        self.problem: GroundTaskNetwork | None = None
        self.knowledge = Knowledge()
        self.pending: dict[str, tuple[str, tuple[str, ...]]] = {}  # reply-with → (kind, key)
        self.failure: str | None = None
        self.actions: list[tuple[object, ...]] = []
        self.started = 0.0
        return FSM(
            initial="idle",
            states={
                "idle": Behaviour(
                    "idle",
                    self._idle,
                    terminal=lambda: self.request is not None,
                    doc="await a planning problem from a_co",
                ),
                "initialize": Behaviour(
                    "initialize",
                    self._collect,
                    terminal=lambda: not self.pending or self.failure is not None,
                    on_enter=self._ask,
                    doc="query a_km for the knowledge the problem needs",
                ),
                "search": Behaviour(
                    "search",
                    self._search,
                    terminal=lambda: True,
                    waits=False,
                    doc="HTN search for a plan (GTPyhop)",
                ),
                "finalize": Behaviour(
                    "finalize",
                    self._finalize,
                    terminal=lambda: True,
                    waits=False,
                    doc="build the hierarchical plan; reply to a_co",
                ),
            },
            arcs=[
                Arc("idle", "initialize"),
                Arc("initialize", "search", lambda: self.failure is None, "knowledge complete"),
                Arc("initialize", "finalize", lambda: self.failure is not None, "knowledge missing"),
                Arc("search", "finalize"),
                Arc("finalize", "idle"),
            ],
        )

    def _idle(self) -> None:
        item = self.take(lambda i: i.sender == "a_co" and i.performative is Performative.REQUEST)
        if item is None:
            self.reject_unhandled(lambda i: i.local)
            return
        if not isinstance(item.content, GroundTaskNetwork):
            self.reply(item, Performative.REFUSE, PlanFailure(task_id="", reason="no ground task network"))
            return
        self.request, self.problem = item, item.content
        self.knowledge, self.failure, self.actions = Knowledge(), None, []
        self.started = time.monotonic()
        self.log.info(
            "planning #%d for %s: %s",
            item.content.plan_index,
            item.content.task_id,
            [(t.name, t.args) for t in item.content.tasks],
        )

    def _query(self, kind: str, key: tuple[str, ...], query: msgspec.Struct) -> None:
        msg = self.send(
            "a_km",
            Performative.QUERY_REF,
            query,
            protocol="fipa-query",
            reply_by_s=QUERY_REPLY_BY_S,
        )
        assert msg.reply_with is not None
        self.pending[msg.reply_with] = (kind, key)
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
            for arm in ARMS:
                self._query("grasps", (obj, arm), GraspQuery(object=obj, arm=arm))
            if obj != SURFACE:
                self._query("placement", (obj, SURFACE), PlacementQuery(object=obj, surface=SURFACE))
        for t in self.problem.tasks:
            if t.name == "pour" and len(t.args) == 2:
                self._query("pour", t.args, PourQuery(source=t.args[0], target=t.args[1]))

    def _collect(self) -> None:
        for item in list(self.x):
            entry = self.pending.pop(item.msg.in_reply_to or "", None)
            if entry is None:
                continue
            self.x.remove(item)
            kind, key = entry
            if item.performative is not Performative.INFORM_REF or not isinstance(item.content, Answer):
                reason = item.msg.content.decode("utf-8", "replace") or item.performative.value
                if kind == "object" and not key[0].endswith("_gripper"):
                    self.failure = f"I know of no {key[0]} ({reason})"
                continue
            self._learn(kind, key, item.content)
        self.reject_unhandled(lambda i: i.local or i.sender == "a_co")

    def _learn(self, kind: str, key: tuple[str, ...], answer: Answer) -> None:
        k = self.knowledge
        if kind in ("object", "scene"):
            for info in answer.objects:
                k.objects[info.name] = info
        elif kind == "grasps":
            k.grasps[(key[0], key[1])] = answer.grasps
        elif kind == "placement" and answer.placement is not None:
            k.placements[(key[0], key[1])] = answer.placement
        elif kind == "pour":
            k.pours[(key[0], key[1])] = answer.pour

    def _search(self) -> None:
        assert self.problem is not None
        try:
            for t in self.problem.tasks:
                root = f"{t.name}({','.join(t.args)})"
                self.actions.extend(find_plan(self.knowledge, (t.name, *t.args), root))
        except PlanningFailure as exc:
            self.failure = str(exc)
        except Exception as exc:  # a bug in the domain must not take a_pl down
            self.log.exception("planner error")
            self.failure = f"planner error: {exc}"

    def _finalize(self) -> None:
        assert self.request is not None and self.problem is not None
        elapsed = time.monotonic() - self.started
        if self.failure is not None:
            self.reply(
                self.request,
                Performative.FAILURE,
                PlanFailure(task_id=self.problem.task_id, reason=self.failure),
            )
            self.log.info("no plan: %s", self.failure)
        else:
            root, complete, cost = to_hfsm(self.actions)
            plan = HierarchicalPlan(
                plan_id=f"{self.problem.task_id}-p{self.problem.plan_index}",
                task_id=self.problem.task_id,
                root=root,
                complete=complete,
                cost=cost,
                km_queries=self.knowledge.queries,
                planning_time_s=round(elapsed, 3),
            )
            self.reply(self.request, Performative.INFORM, plan)
            self.log.info(
                "plan %s: %d leaves, %s, %.1f s expected, %d queries, %.3f s",
                plan.plan_id,
                len(root.leaves()),
                "complete" if complete else "partial",
                cost,
                self.knowledge.queries,
                elapsed,
            )
        self.request = self.problem = None
        self.pending.clear()
