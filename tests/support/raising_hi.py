"""A planted a_hi for tests: the handler of a_co's progress (C2, fipa-subscribe inform) raises
the first time it is called in the process; the runtime logs and counts it (``handler_errors``,
services/runtime/roles/) and a_hi goes on: one progress line is not said to the person, the
task is unharmed. A test names it as a_hi's implementation in a copy of the specification
(``ROCO_SPEC``); roco itself never starts it."""

from __future__ import annotations

from services.agents.human_interface.agent import HumanInterface
from shared.fipa_codec.languages.l_hc import Progress


class RaisingHumanInterface(HumanInterface):
    """:class:`HumanInterface` whose first progress report raises."""

    raised = False

    def _on_progress(self, progress: Progress) -> None:
        if not self.raised:
            self.raised = True
            raise RuntimeError("planted: a_hi's progress handler raises once")
        super()._on_progress(progress)
