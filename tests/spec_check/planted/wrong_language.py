"""Planted fault: a_pl's role on C3 speaks L_WM, a language C3 does not carry."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from services.runtime.roles import participant


class Planner(Base):
    ROLES = (participant("C3", "fipa-request", "L_WM"), Base.ROLES[1])
