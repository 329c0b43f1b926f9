"""Planted fault: a_pl declares itself the initiator on C3, where the specification makes it
the participant."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from services.runtime.roles import initiator


class Planner(Base):
    ROLES = (initiator("C3", "fipa-request", "L_HFSM"), Base.ROLES[1])
