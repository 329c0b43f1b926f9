"""ag_ex on the communication side (paper §5.3): the participant of fipa-request on C5.

It hands each L_EX command from a_ta to the hard-timing executor (``velma.executor``), which
runs the control loop in its own thread, and answers with the result: ``inform`` with an
L_EX CommandResult (or an L_SD Observation for ``observe``), or ``failure`` with the
CommandResult that says why. Results cross from the loop thread through the agent's receptor
buffer; nothing here blocks the loop. ``ROCO_REALTIME=1`` paces the simulation to wall time.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import msgspec

from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Behaviour
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_ex import CommandResult, ExecutorCommand
from shared.fipa_codec.languages.l_sd import Observation

COMMAND_TYPES = tuple(t for t in ExecutorCommand.__args__)


@dataclass(frozen=True)
class Done:
    """A command's result from the loop thread, with the request it answers."""

    request: Received
    result: CommandResult | Observation


class ExecutorAgent(Agent):
    name = "ag_ex"

    def make_executor(self) -> Any:
        """The hard-timing executor this agent serves (velma's, pacing from ROCO_REALTIME)."""
        from velma.executor import Executor

        return Executor(realtime=os.environ.get("ROCO_REALTIME", "0") == "1")

    def build_fsm(self) -> FSM:
        self.executor = self.make_executor()
        return FSM(
            initial="serve",
            states={
                "serve": Behaviour(
                    "serve",
                    self._serve,
                    terminal=lambda: False,
                    doc="pass a_ta's commands to the control loop; answer with their results",
                )
            },
        )

    def setup(self) -> None:
        self.executor.start()

    def close(self) -> None:
        self.executor.stop()

    def _serve(self) -> None:
        while self.x:
            item = self.x.popleft()
            if item.performative is Performative.REQUEST and isinstance(item.content, COMMAND_TYPES):
                command: msgspec.Struct = item.content
                self.executor.submit(command, lambda result, req=item: self.post(Done(req, result)))
            elif item.performative is Performative.CANCEL:
                self.log.info("cancel from %s: the running command completes, queued ones stay", item.sender)
            elif item.performative is not Performative.NOT_UNDERSTOOD and not item.local:
                self.not_understood(
                    item.sender, item.channel, f"cannot serve {item.performative.value}", item.msg
                )
        while self.r:
            event = self.r.popleft()
            if isinstance(event, Done):
                ok = not isinstance(event.result, CommandResult) or event.result.ok
                self.reply(event.request, Performative.INFORM if ok else Performative.FAILURE, event.result)
