"""a_cv — conveyor: moves items on the belt to a bin (cell.toml, C2).

A simplification: the belt is a counter per bin, with no physics and no time to move; a move
to a bin it does not have is refused, and one that would overfill a bin fails.
"""

from __future__ import annotations

from cell.names import C2, FIPA_REQUEST, L_BELT
from cell.terms import Move, Moved, Stuck
from services.runtime.agent import FSM, Agent, Behaviour
from services.runtime.roles import PARTICIPANT, Conversation, handles, participant
from shared.fipa_codec import Performative

BINS = 4
"""The belt's bins, numbered 1..BINS."""
BIN_CAPACITY = 100
"""Items a bin holds."""


class Conveyor(Agent):
    name = "a_cv"
    ROLES = (participant(C2, FIPA_REQUEST, L_BELT),)

    def build_fsm(self) -> FSM:
        self.bins = [0] * (BINS + 1)  # index 0 unused: bins are numbered from 1
        return FSM(
            [Behaviour("serve", self.handle_received, terminal=lambda: False, doc="move what a_so asks")]
        )

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_request(self, conv: Conversation) -> None:
        """a_so asks to move items to a bin: refused for a bin the belt does not have or a count
        below 1, failed when the bin would overflow; else agreed and done."""
        move = conv.content
        if not isinstance(move, Move) or not 1 <= move.bin <= BINS or move.count < 1:
            conv.reply(
                Performative.REFUSE, Stuck(reason=f"the belt has bins 1..{BINS} and moves 1 item or more")
            )
            return
        conv.reply(Performative.AGREE)
        if self.bins[move.bin] + move.count > BIN_CAPACITY:
            conv.reply(Performative.FAILURE, Stuck(reason=f"bin {move.bin} would overflow"))
            return
        self.bins[move.bin] += move.count
        self.counters["moved"] += move.count
        conv.reply(Performative.INFORM, Moved(count=move.count, bin=move.bin, total=self.bins[move.bin]))
