"""a_hi — the human interface (paper §5.2): takes commands from a person and reports outcomes.

Receptor: ``roco/human/in`` (sentences). Effector: ``roco/human/out`` (reports). Towards a_co
it is the initiator of fipa-request on C2, content in L_HC.
"""

from __future__ import annotations

import msgspec

from services.human_interface.language import NotUnderstood, interpret
from services.human_interface.messages import HumanInput, HumanReport, ReportKind
from services.runtime import keys
from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Behaviour
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand

REQUEST = "fipa-request"
COMMAND_REPLY_BY_S = 3600.0


class HumanInterface(Agent):
    name = "a_hi"

    def build_fsm(self) -> FSM:
        self.requests: dict[str, str] = {}  # conversation-id → request_id
        return FSM(
            initial="interact",
            states={
                "interact": Behaviour(
                    "interact",
                    self._interact,
                    terminal=lambda: False,
                    doc="turn sentences into requests to a_co; report a_co's answers",
                )
            },
        )

    def setup(self) -> None:
        decoder = msgspec.json.Decoder(HumanInput)

        def on_text(key: str, payload: bytes) -> None:
            try:
                self.post(decoder.decode(payload))
            except msgspec.DecodeError as exc:
                self.log.warning("ignored malformed human input: %s", exc)

        self.transport.subscribe(keys.HUMAN_IN, on_text)

    def _report(self, request_id: str, kind: ReportKind, text: str) -> None:
        self.log.info("to person [%s] %s: %s", request_id, kind.value, text)
        self.emit(
            keys.HUMAN_OUT, msgspec.json.encode(HumanReport(request_id=request_id, kind=kind, text=text))
        )

    def _interact(self) -> None:
        while self.r:
            event = self.r.popleft()
            if isinstance(event, HumanInput):
                self._command(event)
        while self.x:
            self._answer(self.x.popleft())

    def _command(self, event: HumanInput) -> None:
        try:
            goal = interpret(event.text)
        except NotUnderstood as exc:
            self._report(event.request_id, ReportKind.NOT_UNDERSTOOD, str(exc))
            return
        msg = self.send(
            "a_co",
            Performative.REQUEST,
            HumanCommand(text=event.text, goal=goal, priority=event.priority),
            protocol=REQUEST,
            conversation_id=f"cmd-{event.request_id}",
            reply_by_s=COMMAND_REPLY_BY_S,
        )
        assert msg.conversation_id is not None
        self.requests[msg.conversation_id] = event.request_id

    def _answer(self, item: Received) -> None:
        request_id = self.requests.get(item.msg.conversation_id or "")
        if request_id is None:
            if item.performative is not Performative.NOT_UNDERSTOOD:
                self.not_understood(item.sender, item.channel, "no such command conversation", item.msg)
            return
        perf = item.performative
        if perf is Performative.AGREE:
            self._report(request_id, ReportKind.ACCEPTED, "a_co accepted the command")
            return
        self.requests.pop(item.msg.conversation_id or "", None)
        if isinstance(item.content, CommandOutcome):
            succeeded = perf is Performative.INFORM and item.content.succeeded
            self._report(
                request_id, ReportKind.SUCCEEDED if succeeded else ReportKind.FAILED, item.content.detail
            )
        else:
            reason = item.msg.content.decode("utf-8", "replace") or "no reason given"
            self._report(request_id, ReportKind.FAILED, f"a_co answered {perf.value}: {reason}")
