"""A subscriber to a_km's changes of the scene, for tests: a_wt of docs/spec.md's walk-through
(its first channel, the next free one, carries fipa-subscribe from a_wt to a_km; its warnings
on the second are not sent here)
(tests/agents/knowledge/test_scene_subscription.py). A module of its own: the runtime reads
an agent's module for sends outside its roles."""

from __future__ import annotations

import queue

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.roles import INITIATOR, Conversation, handles, initiator
from services.runtime.transport import Transport
from services.spec.model import SystemSpec
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_wm import SceneChange, SceneSubscription
from tests.spec_check.walkthrough import NEXT


class Watcher(Agent):
    """a_wt as docs/spec.md says a new agent subscribes: an initiator role that keeps its
    subscription open (``resubscribes``), subscribing again when a_km's token reappears."""

    name = "a_wt"
    ROLES = (
        initiator(NEXT.notice_channel_name, "kitchen-warning", "L_HC", unused=True),
        initiator(NEXT.channel_name, "fipa-subscribe", "L_WM", reply_by_s=2.0, resubscribes=True),
    )

    def __init__(self, transport: Transport, spec: SystemSpec) -> None:
        super().__init__(transport, spec)
        self.agreed: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.changes: queue.SimpleQueue[SceneChange] = queue.SimpleQueue()

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("watch", self.handle_received, terminal=lambda: False, doc="take in changes")])

    def setup(self) -> None:
        self.roles.subscribe(
            NEXT.channel_name,
            "fipa-subscribe",
            SceneSubscription(objects=("jar",)),
            conversation_id="wt-scene",
            retry_s=(0.0, 0.0),
            while_away=False,
            on_subscribed=lambda conv: self.agreed.put(conv.conversation_id),
        )

    @handles("fipa-subscribe", INITIATOR, Performative.INFORM)
    def _on_change(self, conv: Conversation) -> None:
        if isinstance(conv.content, SceneChange):
            self.changes.put(conv.content)
