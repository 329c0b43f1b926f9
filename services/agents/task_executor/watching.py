"""a_ta's side of the watch: a_km asks for it, ag_ex does it, a_ta passes on what it sees.

a_km subscribes on C6 (fipa-subscribe, FIPA SC00035) with an L_WM ``Subscription`` of topic
:data:`TOPIC` and a ``period_s`` while someone needs to know of changes of the scene quickly
(services/agents/knowledge/watch_demand.py). a_ta agrees and subscribes in turn to ag_ex's watch
on C5 (L_EX ``Watch``: a head-camera frame every ``period_s`` of robot time, informed as an
L_SD ``Observation``, velma/executor/watch.py); each frame goes to a_km as an observation of
the environment subscription, as a_ta's own Observes do (``observed_update``). A watched frame
is not a look of the plan: a_ta's task decisions, its replanning among them, stay on its own
Observes. a_km's ``cancel`` (or a_km gone) cancels the watch at ag_ex. a_ta's role keeps the
watch at ag_ex asked while a_km wants it (services/runtime/roles/subscriptions.py: again after a
refusal, a failure or no answer, and when a restarted ag_ex comes back).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

from services.runtime.roles import Conversation, StandingSubscription
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_ex import Watch
from shared.fipa_codec.languages.l_wm import Subscription

TOPIC = "watch"
"""The ``Subscription.topic`` by which a_km asks a_ta to have the robot watch."""
PERIOD_RANGE_S = (0.1, 5.0)
"""The ``period_s`` (robot s) a_ta accepts."""
WATCH_REPLY_BY_S = 10.0
"""How long (s) ag_ex may take to agree to the watch (its camera may be starting)."""


def period_problem(sub: Subscription) -> str | None:
    """Why a_ta does not take the watch ``sub`` (None: it does)."""
    low, high = PERIOD_RANGE_S
    p = sub.period_s
    if p is None or not math.isfinite(p) or not low <= p <= high:
        return f"a watch period is {low}..{high} s of robot time, not {p}"
    return None


class WatchRelay:
    """The watch a_km asked of a_ta (module docstring): ``subscribe`` has a_ta's role keep a
    ``Watch`` subscription to ag_ex open on C5, ``unsubscribe`` ends it."""

    def __init__(
        self,
        subscribe: Callable[[Watch], StandingSubscription],
        unsubscribe: Callable[[StandingSubscription], None],
        log: logging.Logger,
    ) -> None:
        self._subscribe = subscribe
        self._unsubscribe = unsubscribe
        self.log = log
        self.asked_by: Conversation | None = None
        """a_km's subscription (None: no watch asked)."""
        self.at_ex: StandingSubscription | None = None
        """The watch asked of ag_ex (None: none)."""
        self.frames = 0

    def asked(self, conv: Conversation, sub: Subscription) -> None:
        """a_km subscribed ``sub`` (topic :data:`TOPIC`) in ``conv``: agree and have ag_ex watch,
        or refuse a period out of range. A later one replaces the one before."""
        why = period_problem(sub)
        if why is not None or sub.period_s is None:
            conv.refuse_with(Performative.REFUSE, why or "no period")
            return
        self.asked_by = conv
        conv.reply(Performative.AGREE)
        self._end_at_ex()
        self.at_ex = self._subscribe(Watch(objects=(), period_s=sub.period_s))
        self.log.info(
            "asked ag_ex to watch every %.2f s of robot time (%s)", sub.period_s, self.at_ex.base_id
        )

    def cancelled(self, conv: Conversation) -> bool:
        """a_km cancelled ``conv``: True when it was the watch (then it is cancelled at ag_ex)."""
        if conv is not self.asked_by:
            return False
        self.stop("a_km cancelled it")
        return True

    def stop(self, why: str) -> None:
        """No watch is needed any more (``why``): cancel it at ag_ex."""
        if self.asked_by is None:
            return
        self.asked_by = None
        self._end_at_ex()
        self.log.info("the watch ends (%s) after %d frames", why, self.frames)

    def is_frame(self, conv: Conversation) -> bool:
        """Whether an inform of ``conv`` is a frame of the watch (else it is something else's)."""
        return self.at_ex is not None and self.at_ex.owns(conv) and not conv.answers_cancel

    def _end_at_ex(self) -> None:
        sub, self.at_ex = self.at_ex, None
        if sub is not None:
            self._unsubscribe(sub)
