"""a_p of tests/runtime/test_roles.py: the participant of every protocol on C1."""

from __future__ import annotations

from typing import ClassVar

from services.runtime.roles import PARTICIPANT, Conversation, handles, spec_roles
from services.spec.names import FIPA_SUBSCRIBE
from tests.support.role_agents import DONE, RUNNING, SPEC, P, Script, Scripted, handling_all


class Participant(Scripted):
    name = "a_p"
    ROLES = tuple(spec_roles(SPEC, "a_p"))
    script: ClassVar[Script] = {
        ("fipa-request", "request"): [(P.AGREE, None), (P.INFORM, None)],
        ("fipa-query", "query-ref"): [(P.INFORM_REF, None)],
        ("fipa-request-when", "request-when"): [(P.AGREE, None), (P.INFORM, None)],
        ("fipa-subscribe", "subscribe"): [(P.AGREE, None), (P.INFORM, None)],
        ("fipa-subscribe", "cancel"): [(P.INFORM, None)],
        ("fipa-propose", "propose"): [(P.ACCEPT_PROPOSAL, None)],
        ("fipa-contract-net", "cfp"): [(P.PROPOSE, None)],
        ("fipa-contract-net", "accept-proposal"): [(P.INFORM, None)],
        ("fipa-iterated-contract-net", "cfp"): [(P.PROPOSE, None)],
        ("fipa-iterated-contract-net", "accept-proposal"): [(P.INFORM, None)],
        ("fipa-english-auction", "cfp"): [(P.PROPOSE, None)],
        ("fipa-dutch-auction", "cfp"): [(P.PROPOSE, None)],
        ("fipa-brokering", "proxy"): [(P.AGREE, None), (P.INFORM, None)],
        ("fipa-recruiting", "proxy"): [(P.AGREE, None), (P.INFORM, None)],
        ("coordinate", "request"): [(P.INFORM, RUNNING)],
        ("coordinate", "confirm"): [(P.INFORM, DONE)],
    }
    on_request = handling_all(PARTICIPANT, Scripted.handle)

    @handles(FIPA_SUBSCRIBE, PARTICIPANT, P.CANCEL)
    def on_unsubscribe(self, conv: Conversation) -> None:
        self.handle(conv)
