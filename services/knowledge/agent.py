"""a_km — the knowledge manager (paper §5.5, Table 5, Figure 11c).

FSM states: idle (wait for a query from a_pl or a_ta, or an observation), questionAnswering
(answer one query from the knowledge base: inform-ref with an L_WM Answer, or failure with
the reason), knowledgeSaving (apply one observation). At start-up it opens the
fipa-subscribe conversation with a_ta for environment updates, repeating the subscribe
until a_ta agrees (a_ta may start later).
"""

from __future__ import annotations

from services.knowledge.world_model import KnowledgeError, Query, WorldModel
from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Arc, Behaviour
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_wm import (
    GraspQuery,
    ObjectQuery,
    PlacementQuery,
    PourQuery,
    SceneQuery,
    SparqlQuery,
    Subscription,
    WorldUpdate,
)

QUERY_TYPES = (SparqlQuery, ObjectQuery, SceneQuery, GraspQuery, PlacementQuery, PourQuery)
SUBSCRIBE_RETRY_S = 2.0


class KnowledgeManager(Agent):
    name = "a_km"

    def build_fsm(self) -> FSM:
        self.world = WorldModel()
        self.subscribe_reply: str | None = None
        self.subscribed = False
        self.current: Received | None = None
        return FSM(
            initial="idle",
            states={
                "idle": Behaviour(
                    "idle",
                    self._idle,
                    terminal=lambda: self.current is not None,
                    doc="await a query or an observation",
                ),
                "questionAnswering": Behaviour(
                    "questionAnswering",
                    self._answer,
                    terminal=lambda: True,
                    waits=False,
                    doc="reason over the knowledge base; reply to the query",
                ),
                "knowledgeSaving": Behaviour(
                    "knowledgeSaving",
                    self._save,
                    terminal=lambda: True,
                    waits=False,
                    doc="update the knowledge base with an observation",
                ),
            },
            arcs=[
                Arc("idle", "questionAnswering", self._is_query_current, "query"),
                Arc("idle", "knowledgeSaving", lambda: not self._is_query_current(), "observation"),
                Arc("questionAnswering", "idle"),
                Arc("knowledgeSaving", "idle"),
            ],
        )

    def setup(self) -> None:
        self._subscribe()

    def _subscribe(self) -> None:
        msg = self.send(
            "a_ta",
            Performative.SUBSCRIBE,
            Subscription("environment"),
            protocol="fipa-subscribe",
            conversation_id="km-environment",
            reply_by_s=SUBSCRIBE_RETRY_S,
        )
        self.subscribe_reply = msg.reply_with

    def _is_query_current(self) -> bool:
        return self.current is not None and self.current.performative in (
            Performative.QUERY_REF,
            Performative.QUERY_IF,
        )

    def _idle(self) -> None:
        self.current = None
        while self.x:
            item = self.x.popleft()
            if (
                item.msg.in_reply_to == self.subscribe_reply
                and item.msg.conversation_id == "km-environment"
                and item.performative is not Performative.INFORM
            ):
                if item.performative is Performative.AGREE:
                    self.subscribed = True
                    self.log.info("a_ta agreed to send environment updates")
                elif item.local or item.performative in (Performative.REFUSE, Performative.NOT_UNDERSTOOD):
                    self._subscribe()
                continue
            if item.performative in (Performative.QUERY_REF, Performative.QUERY_IF):
                self.current = item
                return
            if item.performative is Performative.INFORM and isinstance(item.content, WorldUpdate):
                self.current = item
                return
            if item.performative is Performative.FAILURE and item.msg.conversation_id == "km-environment":
                self.subscribed = False
                self._subscribe()
                continue
            if not item.local and item.performative is not Performative.NOT_UNDERSTOOD:
                self.not_understood(
                    item.sender, item.channel, f"unexpected {item.performative.value}", item.msg
                )

    def _answer(self) -> None:
        item = self.current
        assert item is not None
        if not isinstance(item.content, QUERY_TYPES):
            self.reply(item, Performative.REFUSE)
            return
        query: Query = item.content
        try:
            answer = self.world.answer(query)
        except KnowledgeError as exc:
            self.log.info("query %s failed: %s", type(query).__name__, exc)
            self.fail(item, Performative.FAILURE, str(exc))
            return
        self.reply(item, Performative.INFORM_REF, answer)

    def _save(self) -> None:
        item = self.current
        assert item is not None and isinstance(item.content, WorldUpdate)
        n = self.world.apply(item.content)
        self.log.info("saved %d object updates (t=%.2f)", n, item.content.stamp)
