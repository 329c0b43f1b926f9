"""a_l of tests/runtime/test_declared_protocol.py: the participant of ``notify`` and ``tell`` on C1."""

from __future__ import annotations

from typing import ClassVar

from services.runtime.roles import PARTICIPANT, Conversation, handles, spec_roles
from shared.fipa_codec import Performative
from tests.support.notify_agents import NOTIFY, SPEC, TELL
from tests.support.role_agents import RUNNING, Script, Scripted


class Listener(Scripted):
    name = "a_l"
    ROLES = tuple(spec_roles(SPEC, "a_l"))
    script: ClassVar[Script] = {(TELL, "inform"): [(Performative.CONFIRM, RUNNING)]}

    @handles(NOTIFY, PARTICIPANT, Performative.INFORM)
    @handles(TELL, PARTICIPANT, Performative.INFORM)
    def on_inform(self, conv: Conversation) -> None:
        self.handle(conv)
