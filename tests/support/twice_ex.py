"""A planted ag_ex for tests: its loop runs the first Observe it is asked for twice and answers
once (the first run's result is dropped), as an ag_ex that executed a request again would. The
robot does nothing wrong that anyone sees: only ag_ex's ledger (velma/executor/ledger.py) shows
the second run. A test names it as ag_ex's implementation in a copy of the specification
(``ROCO_SPEC``); roco itself never starts it."""

from __future__ import annotations

from services.agents.executor.agent import ExecutorAgent
from services.runtime.roles import PARTICIPANT, Conversation, handles
from services.spec.names import FIPA_REQUEST
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_ex import Observe


class TwiceExecutor(ExecutorAgent):
    """:class:`ExecutorAgent` that submits its first Observe to the loop twice."""

    planted = False

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_request(self, conv: Conversation) -> None:
        if not self.planted and isinstance(conv.content, Observe):
            self.planted = True
            self.track(self.executor.submit(conv.content, lambda _result: None), conv)
        super()._on_request(conv)
