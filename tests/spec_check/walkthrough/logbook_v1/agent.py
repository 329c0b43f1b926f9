"""Walk-through, stage 3 (docs/spec.md): the logbook agent's first draft. It has an FSM but
does not handle a_hi's requests yet, so ``roco spec verify-code`` names what is missing."""

from __future__ import annotations

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour


class Logbook(Agent):
    name = "a_lb"

    def build_fsm(self) -> FSM:
        return FSM(initial="idle", states={"idle": Behaviour("idle", lambda: None, terminal=lambda: False)})
