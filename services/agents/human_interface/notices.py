"""How many notices a_hi passes on to the person (protocol ``roco-notify``, L_HC ``Notice``:
shared/fipa_codec/languages/l_hc.py): at most ``NOTICES_PER_S`` (services/runtime/human.py)
per sender in each one-second window; the excess is counted and dropped, with one log line per
sender and window, so that an agent that floods a_hi neither floods the person nor a_hi's log."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from services.runtime.agent import NOTICES_PER_S

WINDOW_S = 1.0
"""The length of a window, in seconds of the gate's clock."""
MAX_SENDERS = 1024
"""Senders whose window the gate remembers; past that, the windows that have ended are
forgotten (a sender with an open window is never forgotten before its window ends)."""


@dataclass
class _Window:
    start: float
    passed: int = 0
    dropped: int = 0


class NoticeGate:
    """Admits or drops each notice by its sender (module docstring). ``clock``: seconds that
    never go back (a_hi's ``sources.monotonic``); ``log``: where a dropping is said, once per
    sender and window. Not thread-safe: call from a_hi's thread."""

    def __init__(
        self,
        log: logging.Logger,
        clock: Callable[[], float] = time.monotonic,
        per_s: int = NOTICES_PER_S,
    ) -> None:
        if per_s < 1:
            raise ValueError(f"per_s must be ≥ 1, not {per_s}")
        self.log = log
        self.clock = clock
        self.per_s = per_s
        self.dropped = 0
        """Notices dropped since the gate was made, over all senders."""
        self._windows: dict[str, _Window] = {}

    def admit(self, sender: str) -> bool:
        """Whether the notice ``sender`` sends now is passed on; False counts it as dropped."""
        now = self.clock()
        w = self._windows.get(sender)
        if w is None or now - w.start >= WINDOW_S:
            self._forget_ended(now)
            w = self._windows[sender] = _Window(now)
        if w.passed < self.per_s:
            w.passed += 1
            return True
        w.dropped += 1
        self.dropped += 1
        if w.dropped == 1:
            self.log.warning(
                "notices from %s: more than %d in %.0f s; the rest of this second's are dropped",
                sender,
                self.per_s,
                WINDOW_S,
            )
        return False

    def _forget_ended(self, now: float) -> None:
        if len(self._windows) >= MAX_SENDERS:
            self._windows = {s: w for s, w in self._windows.items() if now - w.start < WINDOW_S}
