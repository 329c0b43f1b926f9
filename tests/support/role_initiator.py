"""a_i of tests/runtime/test_roles.py: the initiator of every protocol on C1."""

from __future__ import annotations

from typing import ClassVar

from services.runtime.roles import INITIATOR, RoleDecl, spec_roles
from tests.support.role_agents import CANCEL, SPEC, TIMEOUT, P, Script, Scripted, handling_all


class Initiator(Scripted):
    name = "a_i"
    ROLES = tuple(
        RoleDecl(r.channel, r.protocol, r.role, r.languages, reply_by_s=TIMEOUT)
        for r in spec_roles(SPEC, "a_i")
    )
    script: ClassVar[Script] = {
        ("fipa-contract-net", "propose"): [(P.ACCEPT_PROPOSAL, None)],
        ("fipa-iterated-contract-net", "propose"): [(P.ACCEPT_PROPOSAL, None)],
        # the bid is taken, the auction ends, and the winner is asked to complete the sale
        ("fipa-english-auction", "propose"): [(P.ACCEPT_PROPOSAL, None), (P.INFORM, None), (P.REQUEST, None)],
        ("fipa-dutch-auction", "propose"): [(P.ACCEPT_PROPOSAL, None), (P.INFORM, None), (P.REQUEST, None)],
        ("coordinate", "inform"): [(P.CONFIRM, None)],
        ("fipa-subscribe", "inform"): [(CANCEL, None)],
    }
    on_answer = handling_all(INITIATOR, Scripted.handle)
