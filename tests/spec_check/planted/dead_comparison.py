"""Planted fault: a_pl's handler of plan requests is removed and replaced by a comparison
that never runs."""

from __future__ import annotations

from services.agents.planner.agent import Planner as Base
from shared.fipa_codec import Performative


class Planner(Base):
    ROLES = Base.ROLES
    _on_request = None  # type: ignore[assignment]

    def _idle(self) -> None:
        if self.engine.x and self.engine.x[0].performative is Performative.REQUEST:
            return
        super()._idle()
