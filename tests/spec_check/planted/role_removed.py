"""Planted fault: a_pl's fipa-query role towards a_km (C4) is removed."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base


class Planner(Base):
    ROLES = (Base.ROLES[0],)
