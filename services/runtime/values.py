"""The values every part of the agent runtime passes around, below the agent that uses them:
a communicate as acquired (:class:`Received`), the error of a communicate the agent may not
send (:class:`SpecViolation`) and the retransmission period that waits for the peer's return
(:data:`RESEND_ON_RETURN`). An agent imports them from services/runtime/agent.py, which
re-exports them.
"""

from __future__ import annotations

import math

import msgspec

from shared.fipa_codec import Communicate
from shared.fipa_codec.acts import Performative

__all__ = ["RESEND_ON_RETURN", "Received", "SpecViolation"]

RESEND_ON_RETURN = math.inf
"""``retry_s`` that retransmits only when the peer's liveliness token reappears (a restarted
peer lost what it was sent), never periodically."""


class SpecViolation(RuntimeError):
    """The agent tried to send a communicate its specified interface does not allow, or one
    its conversation's current protocol state does not allow (the agent's own bug)."""


class Received(msgspec.Struct, frozen=True, gc=False):
    """One acquired communicate: the message, its decoded ``content`` (a term of its
    language, or None), the ``channel`` it came on, ``local`` True for what the runtime
    synthesised (a failure when a reply-by deadline passed, or the not-understood this agent
    answered the peer with: services/runtime/roles/ ``Roles.not_understood_sent``), and the
    message's ``performative`` and ``sender`` name ("" for none), read on every one taken in.
    Built with :meth:`of`. (A msgspec Struct: one is built per communicate taken in, ≈ 10 ×
    cheaper than a frozen dataclass; not tracked by the garbage collector, as a communicate is
    not.)"""

    msg: Communicate
    content: msgspec.Struct | None
    channel: str
    local: bool
    performative: Performative
    sender: str

    @classmethod
    def of(
        cls, msg: Communicate, content: msgspec.Struct | None, channel: str, local: bool = False
    ) -> Received:
        """``msg`` acquired with its ``content`` on ``channel`` (``local``: synthesised)."""
        return cls(msg, content, channel, local, msg.performative, msg.sender.name if msg.sender else "")
