"""Planted fault: a_pl opens a conversation on C2, a channel it does not end."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from shared.fipa_codec.languages.l_hc import StatusQuery


class Planner(Base):
    ROLES = Base.ROLES

    def _done(self) -> None:
        super()._done()
        self.roles.open("C2", "fipa-query", StatusQuery())
