"""A deliberately incomplete a_pl for ``roco spec verify-code``'s tests: it serves plan
requests but has no handler for a_co's cancel, and it proposes, which the specification does
not let a_pl do. Never run."""

from __future__ import annotations

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from shared.fipa_codec import Performative


class Planner(Agent):
    name = "a_pl"

    def build_fsm(self) -> FSM:
        return FSM(initial="idle", states={"idle": Behaviour("idle", self._idle, terminal=lambda: False)})

    def _idle(self) -> None:
        for item in list(self.x):
            if item.performative is Performative.REQUEST:
                self.reply(item, Performative.PROPOSE)
            elif item.msg.in_reply_to is not None:
                self.x.remove(item)
