"""Walk-through, stage 3 (docs/spec.md): a_hi's side of the new channel C9. It plays the
initiator of fipa-request there, asks the logbook to record the outcome of every command that
ends, and counts the logbook's answers."""

from __future__ import annotations

from services.agents.human_interface.agent import HumanInterface as Base
from services.agents.human_interface.agent import OpenCommand
from services.runtime.human import ReportKind
from services.runtime.roles import INITIATOR, Conversation, handles, initiator
from shared.fipa_codec.languages.l_hc import CommandOutcome

RECORD_BY_S = 10.0


class HumanInterface(Base):
    ROLES = (*Base.ROLES, initiator("C9", "fipa-request", "L_HC", reply_by_s=RECORD_BY_S))

    def _end(self, c: OpenCommand, kind: ReportKind, text: str) -> None:
        super()._end(c, kind, text)
        self.record(
            CommandOutcome(command_id=c.conversation_id, succeeded=kind is ReportKind.SUCCEEDED, detail=text)
        )

    def record(self, outcome: CommandOutcome) -> Conversation:
        """Ask the logbook to record ``outcome``."""
        return self.roles.open("C9", "fipa-request", outcome)

    @handles("fipa-request", INITIATOR, "inform", channel="C9")
    def _on_recorded(self, conv: Conversation) -> None:
        self.counters["logbook.recorded"] += 1

    @handles("fipa-request", INITIATOR, "refuse", "failure", channel="C9")
    def _on_not_recorded(self, conv: Conversation) -> None:
        self.counters["logbook.not_recorded"] += 1
        self.log.warning("the logbook did not record %s: %s", conv.conversation_id, conv.reason)
