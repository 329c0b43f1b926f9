"""A stream a fipa-subscribe participant role serves to its latest subscriber (FIPA SC00035).

An agent that informs a subscriber of changes (a_co: a_hi of its commands' progress) declares
its participant role as usual and, in its ``__init__`` once the runtime's has run, asks the
role to serve the stream::

    self.progress = self.roles.serve(
        C2, FIPA_SUBSCRIBE, unsent=lambda: self.note.unsent, about=lambda p: p.command_id,
        kept_each=256, kept_in_all=1024, dropped="progress_dropped",
    )

Its ``subscribe`` handler decides only: ``conv.refuse_with(…)``, or
``self.progress.agree(conv)``; it informs with ``self.progress.inform(content)``. The role
owns the rest of the participant's side:

- the latest agreed subscription takes the stream (:attr:`ServedSubscription.conversation`);
- informs made while none is agreed — before the first subscribe, while one is on its way,
  after a cancel or a not-understood — are kept, in order, and sent right after the next agree
  (FIPA SC00035: the informs follow the agree), so that no change is lost whenever the
  subscription comes; they are kept in the list ``unsent`` gives (a field of the agent's
  ``NOTE``: kept across a restart, services/runtime/state_store.py);
- what is kept is bounded: ``kept_each`` informs per ``about(inform)`` (what it is about,
  e.g. a command) and ``kept_in_all`` in all; past a bound the oldest goes, counted under
  ``dropped`` (the first drop logged at WARNING);
- a ``cancel`` is answered ``inform`` (FIPA SC00026 §2 cancel meta-protocol); a
  ``not-understood`` is never answered (FIPA SC00037 §3.12); either ends that subscription,
  and, if it was the latest agreed, the informs are kept until the next agree;
- a subscription the role kept across a restart (declared ``keep=True``) takes the stream
  again: the runtime takes it back while the agent is built, and the stream, served then,
  takes it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

import msgspec

from services.runtime.roles.conversation import Conversation
from services.runtime.roles.declare import RoleDecl
from services.runtime.roles.host import SubscriptionHost
from shared.fipa_codec.acts import Performative

T = TypeVar("T", bound=msgspec.Struct)


class ServedSubscription(Generic[T]):
    """The stream of informs (each a ``T``) a fipa-subscribe participant role serves to its
    latest agreed subscription, keeping them while none is (module docstring). Built by
    :meth:`services.runtime.roles.Roles.serve`; raises ValueError for a bound below 1."""

    def __init__(
        self,
        roles: SubscriptionHost,
        decl: RoleDecl,
        *,
        unsent: Callable[[], list[T]],
        about: Callable[[T], str],
        kept_each: int,
        kept_in_all: int,
        dropped: str,
    ) -> None:
        if kept_each < 1 or kept_in_all < 1:
            raise ValueError(f"the bounds must be at least 1, not {kept_each} and {kept_in_all}")
        self.roles = roles
        self.decl = decl
        self.peer = roles.peer_of(decl)
        self.unsent = unsent
        self.about = about
        self.kept_each = kept_each
        self.kept_in_all = kept_in_all
        self.dropped = dropped
        self.conversation: Conversation | None = None
        """The latest agreed subscription, which the informs go to (None: none)."""

    # ---- the agent's side ----------------------------------------------------------------
    def agree(self, conv: Conversation) -> None:
        """Agree to the subscription ``conv`` (its ``subscribe`` handler decided to): it takes
        the stream, and the informs kept until a subscription follow the agree, oldest first."""
        self.conversation = conv
        conv.reply(Performative.AGREE)
        unsent = self.unsent()
        if unsent:
            self.roles.host.log.info(
                "sending %d inform(s) kept until a subscription (%s %s)",
                len(unsent),
                self.decl.protocol,
                conv.conversation_id,
            )
        while unsent:
            conv.reply(Performative.INFORM, unsent.pop(0))

    def inform(self, content: T) -> None:
        """Inform the latest agreed subscription of ``content``, or keep it for the next one."""
        if self.conversation is not None:
            self.conversation.reply(Performative.INFORM, content)
            return
        unsent, about = self.unsent(), self.about(content)
        if sum(self.about(kept) == about for kept in unsent) >= self.kept_each:
            del unsent[next(i for i, kept in enumerate(unsent) if self.about(kept) == about)]
            self._dropped(about)
        elif len(unsent) >= self.kept_in_all:
            self._dropped(self.about(unsent.pop(0)))
        unsent.append(content)

    def _dropped(self, about: str) -> None:
        agent = self.roles.host
        agent.counters[self.dropped] += 1
        if agent.counters[self.dropped] == 1:
            agent.log.warning(
                "no %s subscription agreed: the oldest kept inform about %s dropped (at most %d "
                "about each, %d in all, are kept)",
                self.decl.protocol,
                about,
                self.kept_each,
                self.kept_in_all,
            )

    def _ends(self, conv: Conversation) -> None:
        if self.conversation is not None and self.conversation.conversation_id == conv.conversation_id:
            self.conversation = None

    # ---- the role's side -----------------------------------------------------------------
    def take(self, conv: Conversation) -> bool:
        """Act on :attr:`Conversation.last` of ``conv``, a conversation of the served role;
        True when it goes on to the agent's handler (a ``subscribe``)."""
        last = conv.last
        if last is None or last.performative is Performative.SUBSCRIBE:
            return True
        if last.performative is Performative.CANCEL:
            self._ends(conv)
            conv.reply(Performative.INFORM)
        elif last.performative is Performative.NOT_UNDERSTOOD:
            self._ends(conv)
            self.roles.host.log.info(
                "not-understood from %s (conversation %s): the subscription ends",
                conv.peer,
                conv.conversation_id,
            )
        return False

    def taken_back(self, conv: Conversation) -> None:
        """``conv``, a subscription kept across a restart, is taken back: it takes the stream."""
        self.conversation = conv

    def peer_changed(self, alive: bool) -> None:
        """The subscriber's token appeared or disappeared: nothing changes (its subscription
        stands until it cancels it)."""

    def tick(self, now: float) -> None:
        """Nothing is due at a time."""
