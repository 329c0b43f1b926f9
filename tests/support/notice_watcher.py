"""a_wt of tests/agents/human_interface/test_agent_notices.py: tells the person something
through a_hi (``roco-notify`` on C9, notice_agents.py; :class:`WarningWatcher`:
``kitchen-warning``), whatever content the test gives it."""

from __future__ import annotations

import msgspec

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.roles import initiator
from shared.fipa_codec import Performative
from tests.support.notice_agents import CHANNEL, NOTIFY, WARNING, WATCHER


class Watcher(Agent):
    """Sends each content :meth:`tell` is given, in order, on its own thread."""

    name = WATCHER
    period = 0.01
    PROTOCOL = NOTIFY
    ROLES = (initiator(CHANNEL, NOTIFY, "L_HC"),)

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("tell", self._tell, terminal=lambda: False)])

    def tell(self, *contents: msgspec.Struct) -> None:
        """Send each of ``contents`` as a notice's ``inform`` (a conversation each)."""
        self.post(contents)

    def _tell(self) -> None:
        while self.r:
            for content in self.r.popleft():
                self.roles.open(CHANNEL, self.PROTOCOL, content, performative=Performative.INFORM)
        self.handle_received()


class WarningWatcher(Watcher):
    """The watcher of ``WARNING_SPEC``: its notices in ``kitchen-warning``."""

    PROTOCOL = WARNING
    ROLES = (initiator(CHANNEL, WARNING, "L_HC"),)
