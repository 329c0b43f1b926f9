"""The participant's side of a protocol whose initiator confirms each ``inform`` before the
next (roco's coordinate protocol, paper §5.4, Figure 8: a_ta's loop of L_SW informs, each
confirmed by a_co).

A participant role declared ``confirmed_informs=True`` (services/runtime/roles/declare.py) has
the role keep that loop; the agent reports, and decides only what::

    self.reports = self.roles.report(C1, COORDINATE, retry_s=SW_RETRY_S)
    ...
    self.reports.inform(conv, SWStatus(...), final=status.state in TERMINAL_SW_STATES)
    ...
    terminal=lambda: self.reports.final_confirmed(conv)

The role owns the rest:

- one inform at a time: an inform waits, in order, until the peer confirmed the one before it
  (its ``confirm`` answers that inform's reply-with), then goes at once;
- each inform is retransmitted every ``retry_s`` until it is answered (a restarted peer lost
  what it was sent; services/runtime/replies.py);
- a ``not-understood`` that answers the inform awaited (a restarted peer that kept nothing does
  not know the conversation) ends the conversation: nobody will confirm it; it is logged, and
  the informs still waiting in it are not sent (nothing belongs to a conversation after its
  end, FIPA SC00037 §3.12);
- the final inform confirmed (or answered not-understood) is what
  :meth:`ConfirmedInforms.final_confirmed` says.
"""

from __future__ import annotations

from collections import deque

import msgspec

from services.runtime.roles.conversation import Conversation
from services.runtime.roles.declare import RoleDecl
from services.runtime.roles.host import SubscriptionHost
from shared.fipa_codec.acts import Performative

__all__ = ["ConfirmedInforms"]


class ConfirmedInforms:
    """The informs of a participant role declared ``confirmed_informs=True``, sent one at a
    time, each after the peer confirmed the one before (module docstring); ``retry_s`` (s) the
    retransmission period of the inform awaiting its confirm. Built by
    :meth:`services.runtime.roles.Roles.report`."""

    def __init__(self, roles: SubscriptionHost, decl: RoleDecl, *, retry_s: float | None) -> None:
        self.roles = roles
        self.decl = decl
        self.peer = roles.peer_of(decl)
        self.retry_s = retry_s
        self._queue: deque[tuple[Conversation, msgspec.Struct, bool]] = deque()
        self._awaited: tuple[Conversation, str | None, bool] | None = None
        """(conversation, reply-with, final) of the inform awaiting its confirm."""
        self._confirmed: set[Conversation] = set()
        """Conversations whose final inform was confirmed (or answered not-understood)."""

    # ---- the agent's side ----------------------------------------------------------------
    def inform(self, conv: Conversation, content: msgspec.Struct, *, final: bool = False) -> None:
        """Inform the peer of ``content`` in ``conv`` once every inform before it has been
        confirmed (at once when none awaits its confirm); ``final``: the conversation's last
        inform (coordinate: a terminal L_SW state), whose confirm
        :meth:`final_confirmed` tells. Raises SpecViolation (when sent) as
        :meth:`Conversation.send`."""
        if final:
            self._confirmed.discard(conv)
        self._queue.append((conv, content, final))
        self._next()

    def final_confirmed(self, conv: Conversation | None) -> bool:
        """The peer confirmed the final inform of ``conv`` (or answered it not-understood)."""
        return conv is not None and conv in self._confirmed

    def done_with(self, conv: Conversation) -> None:
        """Forget what is known of ``conv``'s final inform (the agent is done with it)."""
        self._confirmed.discard(conv)

    @property
    def awaiting(self) -> bool:
        """An inform awaits its confirm."""
        return self._awaited is not None

    # ---- the role's side -----------------------------------------------------------------
    def take(self, conv: Conversation) -> bool:
        """A communicate received in ``conv`` (:attr:`Conversation.last`): a ``confirm`` or a
        ``not-understood`` is taken here (it ends the wait of the inform it answers, and the
        next inform goes); False for those, True when it goes on to the agent's handler."""
        last = conv.last
        if last is None or last.performative not in (Performative.CONFIRM, Performative.NOT_UNDERSTOOD):
            return True
        if last.performative is Performative.NOT_UNDERSTOOD:
            self.roles.host.log.warning(
                "%s does not know conversation %s: it ended", self.peer, conv.conversation_id
            )
        awaited = self._awaited
        if awaited is not None and awaited[0] is conv and last.msg.in_reply_to == awaited[1]:
            self._awaited = None
            if awaited[2]:
                self._confirmed.add(conv)
            self._next()
        return False

    def _next(self) -> None:
        """Send the first inform waiting, when none awaits its confirm. An inform of a
        conversation that has ended meanwhile (the peer answered not-understood: it does not
        know the conversation, e.g. restarted with nothing kept) is not sent: nothing belongs to
        a conversation after its end (FIPA SC00037 §3.12); a final one counts as confirmed, so
        that the agent does not wait for a confirm that cannot come."""
        while self._awaited is None and self._queue:
            conv, content, final = self._queue.popleft()
            if conv.finished:
                self.roles.host.log.info(
                    "not informing %s in ended conversation %s", self.peer, conv.conversation_id
                )
                if final:
                    self._confirmed.add(conv)
                continue
            reply_with = conv.send(Performative.INFORM, content, retry_s=self.retry_s)
            self._awaited = (conv, reply_with, final)

    def peer_changed(self, alive: bool) -> None:
        """The peer's token came or went: nothing to do (retransmission resends on its return)."""

    def tick(self, now: float) -> None:
        """Nothing is due at a time."""
