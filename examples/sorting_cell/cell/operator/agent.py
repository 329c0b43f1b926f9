"""a_op — operator: reads a person's order, asks the sorter, tells the person the outcome
(cell.toml: role "person", initiator on C1).

It plays the person's role, so ``roco send "sort 3 bolts"`` reaches it and waits for its final
report (services/runtime/person.py). A simplification: it reads one form only, "sort <number>
<item>" (the item singular or plural); any other line is not understood.
"""

from __future__ import annotations

import re

from cell.names import C1, FIPA_REQUEST, L_ORD
from cell.terms import Order, Refused, Sorted
from services.runtime.agent import FSM, MAX_LINE_CHARS, Agent, Behaviour, HumanInput, PersonFace, ReportKind
from services.runtime.roles import INITIATOR, Conversation, handles, initiator
from shared.fipa_codec import Performative

ORDER = re.compile(r"\s*sort\s+(\d{1,3})\s+([a-z]+?)s?\s*", re.IGNORECASE)
"""The one form of order it reads: "sort 3 bolts"."""
ORDER_REPLY_BY_S = 10.0
"""How long (s) it waits for the sorter's answer."""


class Operator(Agent):
    name = "a_op"
    ROLES = (initiator(C1, FIPA_REQUEST, L_ORD, reply_by_s=ORDER_REPLY_BY_S),)

    def build_fsm(self) -> FSM:
        return FSM(
            [Behaviour("interact", self._interact, terminal=lambda: False, doc="turn lines into orders")]
        )

    def setup(self) -> None:
        self.person = PersonFace(self)
        self.person.open()

    def _interact(self) -> None:
        while self.r:
            event = self.r.popleft()
            if isinstance(event, HumanInput):
                self._read(event)
        self.handle_received()

    def _read(self, said: HumanInput) -> None:
        """An order to the sorter, or "not understood" to the person."""
        found = ORDER.fullmatch(said.text) if len(said.text) <= MAX_LINE_CHARS else None
        if found is None:
            self.person.tell(
                said.request_id, ReportKind.NOT_UNDERSTOOD, "say: sort <number> <item>, e.g. sort 3 bolts"
            )
            return
        order = Order(item=found[2].lower(), count=int(found[1]))
        self.roles.open(C1, FIPA_REQUEST, order, data=said.request_id)

    @handles(FIPA_REQUEST, INITIATOR, Performative.AGREE)
    def _on_agree(self, conv: Conversation) -> None:
        order = conv.opening_content(Order)
        self.person.tell(conv.data, ReportKind.ACCEPTED, f"sorting {order.count} {order.item}(s)")

    @handles(FIPA_REQUEST, INITIATOR, Performative.INFORM)
    def _on_sorted(self, conv: Conversation) -> None:
        done = conv.content
        text = done.told() if isinstance(done, Sorted) else "sorted"
        self.person.tell(conv.data, ReportKind.SUCCEEDED, text)

    @handles(FIPA_REQUEST, INITIATOR, Performative.REFUSE, Performative.FAILURE)
    def _on_not_sorted(self, conv: Conversation) -> None:
        why = (
            conv.content.reason
            if isinstance(conv.content, Refused)
            else conv.reason or "the sorter did not answer"
        )
        self.person.tell(conv.data, ReportKind.FAILED, why)
