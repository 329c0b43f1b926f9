"""Planted fault: a_pl answers a plan request with a performative chosen through a variable,
one none of its roles may send (propose). (The request its handler receives, named in
``@handles``, is no such fault: the roles receive it, they need not send it.)"""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from services.runtime.roles import PARTICIPANT, Conversation, handles
from services.spec.names import FIPA_REQUEST
from shared.fipa_codec import Performative


class Planner(Base):
    ROLES = Base.ROLES

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_request(self, conv: Conversation) -> None:
        answer = Performative.PROPOSE
        conv.reply(answer)
