"""Planted fault: a_pl opens a conversation on C7, a channel it does not end, naming channel
and protocol by services/spec/names.py (the enum's member and an alias) rather than as strings."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from services.spec.names import FIPA_QUERY as QUERY
from services.spec.names import Channel
from shared.fipa_codec.languages.l_wm import SparqlQuery


class Planner(Base):
    ROLES = Base.ROLES

    def _done(self) -> None:
        super()._done()
        self.roles.open(Channel.C7, QUERY, SparqlQuery("ASK {}"))
