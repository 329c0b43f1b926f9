"""Planted fault: a_pl answers a plan request with a performative chosen through a variable,
one none of its roles may send (propose)."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from services.runtime.roles import PARTICIPANT, Conversation, handles
from shared.fipa_codec import Performative


class Planner(Base):
    ROLES = Base.ROLES

    @handles("fipa-request", PARTICIPANT, "request")
    def _on_request(self, conv: Conversation) -> None:
        answer = Performative.PROPOSE
        conv.reply(answer)
