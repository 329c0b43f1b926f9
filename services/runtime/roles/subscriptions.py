"""A subscription the fipa-subscribe initiator role keeps open itself (FIPA SC00035).

An agent that subscribes to a peer's stream declares its initiator role with
``resubscribes=True`` (services/runtime/roles/ :func:`~services.runtime.roles.initiator`)
and, in its ``setup``, asks the role for the subscription::

    self.progress = self.roles.subscribe(
        C2, FIPA_SUBSCRIBE, ProgressSubscription(), conversation_id="hi-progress",
        reply_by_s=5.0, retry_s=(1.0, 60.0),
    )

The role then owns what FIPA SC00035 leaves to the initiator, and the agent writes only its
handler of the stream's ``inform``\\s (and, if it wants them, the hooks ``on_subscribed`` and
``on_lost``):

- the first ``subscribe`` goes when the peer's liveliness token appears (at once with
  ``at_start``);
- ``agree`` (or a first ``inform``) of the latest attempt: :attr:`StandingSubscription.subscribed`;
- ``refuse``, ``failure``, ``not-understood`` or a passed reply-by deadline of the latest
  attempt: the next attempt after ``retry_s[0]`` s, the interval doubling up to ``retry_s[1]``
  (0: at once); each attempt in a new conversation (``-2``, ``-3``, … added to the
  conversation-id: a conversation-id names one conversation, FIPA SC00061). Where the agent
  keeps state (services/runtime/state_store.py: a fleet's run folder, compose's volume), the
  count of attempts is kept too (``<agent>.subscriptions.json``), so a restarted agent goes on
  from the next number instead of opening its first attempt's conversation again;
- the peer's token disappears: the subscription is lost; with ``while_away`` the attempts go
  on with the back-off from its first interval, else the next one waits for the token;
- the token appears: the back-off starts again from its first interval, and an attempt goes
  at once when none is subscribed or waiting (without ``while_away``: whenever the token had
  disappeared since, since a restarted peer has lost the subscription); an agreed attempt
  the new one replaces is cancelled (a peer that kept it stops serving it; one that restarted
  answers that it knows no such conversation);
- an earlier attempt that agrees after a later one was made is superfluous: the role cancels
  it (FIPA SC00026 §2 cancel meta-protocol); the ``inform`` answering that cancel does not
  reach the agent, other informs of any attempt do.

A role keeps several subscriptions apart by their conversation-ids (:meth:`StandingSubscription.owns`:
e.g. a_ta's power-ons and its watch, both fipa-subscribe to ag_ex on C5); ``roles.unsubscribe``
ends one: its latest attempt is cancelled and no other follows.
"""

from __future__ import annotations

from collections.abc import Callable

import msgspec

from services.runtime.roles.conversation import Conversation
from services.runtime.roles.declare import RoleDecl
from services.runtime.roles.host import SubscriptionHost
from services.runtime.state_store import StateFile
from shared.fipa_codec.acts import Performative

Hook = Callable[["Conversation"], None]


class StandingSubscription:
    """One subscription a fipa-subscribe initiator role keeps open (module docstring).

    ``content`` is the ``subscribe``'s content, ``conversation_id`` the first attempt's
    conversation-id; ``reply_by_s`` (s) how long each attempt waits for an answer (the
    role's when None); ``retry_s`` (s, s) the first and longest interval between attempts.
    Built by :meth:`services.runtime.roles.Roles.subscribe`."""

    def __init__(
        self,
        roles: SubscriptionHost,
        decl: RoleDecl,
        content: msgspec.Struct,
        *,
        conversation_id: str,
        reply_by_s: float | None,
        retry_s: tuple[float, float],
        at_start: bool,
        while_away: bool,
        on_subscribed: Hook | None,
        on_lost: Hook | None,
    ) -> None:
        if retry_s[0] < 0 or retry_s[1] < retry_s[0]:
            raise ValueError(f"retry_s must be (first, longest) with 0 <= first <= longest, not {retry_s}")
        self.roles = roles
        self.decl = decl
        self.peer = roles.peer_of(decl)
        self.content = content
        self.base_id = conversation_id
        self.reply_by_s = reply_by_s
        self.retry_s = retry_s
        self.while_away = while_away
        self.on_subscribed = on_subscribed
        self.on_lost = on_lost
        self.subscribed = False
        """The peer agreed to the latest attempt (or informed in it) and has not gone since."""
        self.conversation: Conversation | None = None
        """The latest attempt (None before the first)."""
        self.agreed: Conversation | None = None
        """The latest attempt the peer agreed to (None: none yet)."""
        self._kept: StateFile[dict[str, int]] = StateFile.for_agent(
            f"{roles.host.name}.subscriptions", dict[str, int]
        )
        self.attempts = (self._kept.load() or {}).get(conversation_id, 0)
        """Attempts made, by this process and, where kept, the agent's earlier ones."""
        self.pending = False
        """The latest attempt awaits its answer."""
        self.interval = retry_s[0]
        """The interval (s) before the next attempt after a failed one."""
        self.retry_at: float | None = None
        """POSIX time of the next attempt (None: none scheduled)."""
        self.away = False
        """The peer's token disappeared and has not appeared since."""
        if at_start or self.peer in roles.host.peers:
            self._open()

    @property
    def conversation_id(self) -> str | None:
        """The conversation-id of the latest attempt (None before the first)."""
        return self.conversation.conversation_id if self.conversation is not None else None

    def end(self) -> None:
        """No attempt follows (:meth:`services.runtime.roles.dispatch.Roles.unsubscribe` calls it): the
        latest attempt, unless it has ended or is cancelled already, is cancelled."""
        self.retry_at = None
        self.pending = False
        self.subscribed = False
        conv = self.conversation
        if conv is not None and not conv.finished and not conv.cancels:
            conv.stop_awaiting_replies()
            conv.cancel(self.content)

    def _open(self) -> None:
        self.attempts += 1
        n = self.attempts
        cid = self.base_id if n == 1 else f"{self.base_id}-{n}"
        if self._kept.path is not None:  # read again: the agent's other subscriptions count too
            self._kept.save({**(self._kept.load() or {}), self.base_id: n})
        before = self.conversation
        if before is not None:  # the previous attempt is given up (or its peer gone)
            before.stop_awaiting_replies()
            if before is self.agreed and not before.finished and not before.cancels:
                before.cancel(self.content)  # a peer that kept it stops serving it
        self.conversation = self.roles.open(
            self.decl.channel,
            self.decl.protocol,
            self.content,
            conversation_id=cid,
            reply_by_s=self.reply_by_s,
        )
        self.pending = True
        self.retry_at = None

    def _latest(self, conv: Conversation) -> bool:
        return conv.conversation_id == self.conversation_id

    def _retry_later(self) -> None:
        if self.interval <= 0:
            self._open()
            return
        self.retry_at = self.roles.host.sources.time() + self.interval
        self.interval = min(self.interval * 2, self.retry_s[1])

    def _agreed(self, conv: Conversation) -> None:
        self.agreed = conv
        self.subscribed = True
        self.pending = False
        self.retry_at = None
        self.interval = self.retry_s[0]
        log = self.roles.host.log
        log.info("%s agreed to the subscription %s (%s)", self.peer, conv.conversation_id, self.decl.protocol)
        if self.on_subscribed is not None:
            self.on_subscribed(conv)

    # ---- the role's side -----------------------------------------------------------------
    def owns(self, conv: Conversation) -> bool:
        """Whether ``conv`` is one of this subscription's attempts (its conversation-id, or one
        made from it: ``-2``, ``-3``, …), not another conversation the agent opened in the same
        role."""
        cid, base = conv.conversation_id, self.base_id
        return cid == base or (cid.startswith(base + "-") and cid[len(base) + 1 :].isdigit())

    def take(self, conv: Conversation) -> bool:
        """Act on :attr:`Conversation.last` of ``conv``, one of this subscription's
        conversations; True when it goes on to the agent's handler (an ``inform`` of the
        stream)."""
        last = conv.last
        if last is None:
            return False
        perf = last.performative
        if perf is Performative.INFORM:
            if conv.answers_cancel:
                return False  # the answer to the cancel of a superfluous attempt
            if not self.subscribed and self._latest(conv):
                self._agreed(conv)
            return True
        if perf is Performative.AGREE and not last.local:
            if self._latest(conv):
                self._agreed(conv)
            elif not conv.answers_cancel:  # an attempt given up agreed late: the latest one stays
                conv.cancel(self.content)
            return False
        # refuse, failure, not-understood, or the reply-by deadline passed
        if not self._latest(conv) or conv.answers_cancel:
            return False  # an attempt already given up
        log = self.roles.host.log
        (log.debug if self.attempts > 1 else log.info)(
            "%s did not take the subscription %s (%s: %s); subscribing again in %.0f s",
            self.peer,
            conv.conversation_id,
            perf.value if not last.local else "failure",
            conv.reason,
            self.interval,
        )
        was = self.subscribed
        self.subscribed = False
        self.pending = False
        if was and self.on_lost is not None:
            self.on_lost(conv)
        self._retry_later()
        return False

    def peer_changed(self, alive: bool) -> None:
        """The peer's liveliness token appeared (``alive``) or disappeared."""
        if alive:
            back, self.away = self.away, False
            self.interval = self.retry_s[0]
            if (back and not self.while_away) or (not self.subscribed and not self.pending):
                if back:
                    self.roles.host.log.info("%s is back: subscribing again", self.peer)
                self._open()
            return
        self.away = True
        if not self.subscribed:
            return
        self.roles.host.log.warning(
            "%s went away; the subscription %s pauses until it is back", self.peer, self.conversation_id
        )
        self.subscribed = False
        if self.on_lost is not None and self.conversation is not None:
            self.on_lost(self.conversation)
        if self.while_away:
            self.interval = self.retry_s[0]
            self._retry_later()

    def tick(self, now: float) -> None:
        """Make the attempt that is due at POSIX time ``now``, if any."""
        if not self.subscribed and not self.pending and self.retry_at is not None and now >= self.retry_at:
            self._open()
