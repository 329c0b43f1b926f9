"""Planted fault: a_pl tells a_hi about every plan with a send of its own, outside its roles
(no channel joins a_pl and a_hi)."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from shared.fipa_codec import Performative


class Planner(Base):
    ROLES = Base.ROLES

    def _done(self) -> None:
        super()._done()
        self.engine.send("a_hi", Performative.INFORM, None, protocol="fipa-request")
