"""Walk-through, stage 4 (docs/spec.md): the logbook agent records every command outcome a_hi
asks it to (fipa-request on C7) and answers as the protocol says."""

from __future__ import annotations

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import CommandOutcome


class Logbook(Agent):
    name = "a_lb"

    def build_fsm(self) -> FSM:
        self.entries: list[CommandOutcome] = []
        return FSM(
            initial="record", states={"record": Behaviour("record", self._record, terminal=lambda: False)}
        )

    def _record(self) -> None:
        while self.x:
            item = self.x.popleft()
            if item.performative is Performative.REQUEST and isinstance(item.content, CommandOutcome):
                self.entries.append(item.content)
                self.reply(item, Performative.INFORM, item.content)
            elif item.performative is Performative.CANCEL:
                self.fail(item, Performative.FAILURE, "nothing to cancel: entries are recorded at once")
            elif not item.local:
                self.not_understood(item.sender, item.channel, "the logbook only records outcomes", item.msg)
