"""a_n of tests/runtime/test_declared_protocol.py: the initiator of ``notify`` and ``tell`` on C1."""

from __future__ import annotations

from typing import ClassVar

from services.runtime.roles import INITIATOR, Conversation, RoleDecl, handles, spec_roles
from shared.fipa_codec import Performative
from tests.support.notify_agents import SPEC, TELL
from tests.support.role_agents import TIMEOUT, Script, Scripted


class Sender(Scripted):
    name = "a_n"
    ROLES = tuple(
        RoleDecl(r.channel, r.protocol, r.role, r.languages, reply_by_s=TIMEOUT, retry_s=TIMEOUT)
        for r in spec_roles(SPEC, "a_n")
    )
    script: ClassVar[Script] = {}

    @handles(TELL, INITIATOR, Performative.CONFIRM)
    def on_confirm(self, conv: Conversation) -> None:
        self.handle(conv)
