"""When a_km has the robot watch: while a scene subscriber needs to know of changes quickly.

A scene subscription (L_WM ``SceneSubscription``, services/agents/knowledge/scene_watch.py) with
``within_s`` asks to be told of a change within that many seconds of robot time. The robot
learns of changes only by looking, and a_ta looks when its plan does; so while a_km holds at
least one such subscription it asks a_ta for a watch: a second fipa-subscribe on C6 (FIPA
SC00035) with an L_WM ``Subscription`` of topic ``watch`` and a ``period_s`` of
:func:`period_for` — half the shortest ``within_s`` (a change is captured within a period of
its happening, and the frame is observed and told within the next), bounded to
:data:`PERIOD_RANGE_S`. a_ta has ag_ex watch (services/agents/task_executor/watching.py) and
sends the frames as observations of the environment subscription. When the period needed
changes the watch is asked anew (the old one cancelled); when the last such subscriber cancels
or is gone, it is cancelled. a_km's role keeps the watch asked while it is needed
(services/runtime/roles/subscriptions.py: again after a refusal, a failure or no answer, and when a
restarted a_ta comes back).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable

from services.runtime.roles import StandingSubscription
from shared.fipa_codec.languages.l_wm import SceneSubscription, Subscription

TOPIC = "watch"
"""The ``Subscription.topic`` that asks a_ta for a watch."""
WITHIN_RANGE_S = (0.2, 10.0)
"""Accepted ``SceneSubscription.within_s`` (robot s): the camera needs ≈ 0.1–0.6 s of wall time
a frame (docs/bench/observe.md), so sooner cannot be kept."""
PERIOD_RANGE_S = (0.1, 5.0)
"""The ``period_s`` (robot s) a_km asks for, at least and at most."""


def period_for(subscriptions: Iterable[SceneSubscription]) -> float | None:
    """The watch period (robot s) ``subscriptions`` need (module docstring); None when none
    has ``within_s``."""
    within = [s.within_s for s in subscriptions if s.within_s is not None]
    if not within:
        return None
    low, high = PERIOD_RANGE_S
    return min(max(min(within) / 2, low), high)


class WatchDemand:
    """The watch a_km asks of a_ta (module docstring): ``subscribe`` has a_km's role keep a
    ``Subscription`` to a_ta open on C6, ``unsubscribe`` ends it."""

    def __init__(
        self,
        subscribe: Callable[[Subscription], StandingSubscription],
        unsubscribe: Callable[[StandingSubscription], None],
        log: logging.Logger,
    ) -> None:
        self._subscribe = subscribe
        self._unsubscribe = unsubscribe
        self.log = log
        self.period_s: float | None = None
        """The period asked (robot s; None: no watch needed)."""
        self.subscription: StandingSubscription | None = None
        """The watch asked of a_ta (None: none)."""

    def need(self, period_s: float | None) -> None:
        """The watch needed now (``period_s``; None: none): ask, ask anew or cancel."""
        if period_s == self.period_s:
            return
        self.period_s = period_s
        if self.subscription is not None:
            self._unsubscribe(self.subscription)
            self.subscription = None
        if period_s is None:
            self.log.info("no scene subscriber needs changes quickly: the robot's watch is cancelled")
            return
        self.subscription = self._subscribe(Subscription(TOPIC, period_s=period_s))
        self.log.info(
            "a scene subscriber needs changes quickly: a_ta asked to have the robot watch every "
            "%.2f s of robot time (%s)",
            period_s,
            self.subscription.base_id,
        )
