"""a_so — sorter: chooses each ordered item's bin and has the conveyor move the items
(cell.toml: participant on C1, initiator on C2)."""

from __future__ import annotations

from cell.names import C1, C2, FIPA_REQUEST, L_BELT, L_ORD
from cell.terms import Move, Moved, Order, Refused, Sorted, Stuck
from services.runtime.agent import FSM, Agent, Behaviour
from services.runtime.roles import INITIATOR, PARTICIPANT, Conversation, handles, initiator, participant
from shared.fipa_codec import Performative

BIN_OF = {"bolt": 1, "nut": 2, "washer": 3, "screw": 4}
"""Which bin each kind of item goes to."""
MOVE_REPLY_BY_S = 5.0
"""How long (s) the sorter waits for the conveyor's answer to a move."""


class Sorter(Agent):
    name = "a_so"
    ROLES = (
        participant(C1, FIPA_REQUEST, L_ORD),
        initiator(C2, FIPA_REQUEST, L_BELT, reply_by_s=MOVE_REPLY_BY_S),
    )

    def build_fsm(self) -> FSM:
        return FSM(
            [Behaviour("serve", self.handle_received, terminal=lambda: False, doc="sort what is ordered")]
        )

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_request(self, conv: Conversation) -> None:
        """A person's order, through a_op: refused for an item of no bin; else agreed, and the
        conveyor asked to move the items (the order is answered when it answers)."""
        order = conv.content
        if not isinstance(order, Order) or order.item not in BIN_OF:
            kinds = ", ".join(sorted(BIN_OF))
            conv.reply(Performative.REFUSE, Refused(reason=f"the cell sorts {kinds}"))
            return
        conv.reply(Performative.AGREE)
        self.roles.open(C2, FIPA_REQUEST, Move(count=order.count, bin=BIN_OF[order.item]), data=conv)

    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_moved(self, conv: Conversation) -> None:
        """The conveyor moved the items: the order is done."""
        order: Conversation = conv.data
        moved = conv.content
        asked = order.opening_content(Order)
        if isinstance(moved, Moved):
            order.reply(Performative.INFORM, Sorted(item=asked.item, count=moved.count, bin=moved.bin))

    @handles(FIPA_REQUEST, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_stuck(self, conv: Conversation) -> None:
        """The conveyor did not move the items (or did not answer in time): the order failed."""
        order: Conversation = conv.data
        why = (
            conv.content.reason if isinstance(conv.content, Stuck) else conv.reason or "the belt did not move"
        )
        order.reply(Performative.FAILURE, Refused(reason=why))
