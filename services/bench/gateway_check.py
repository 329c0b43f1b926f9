"""The check part 9 of ``roco bench`` (services/bench/gateway.py) makes of its legitimate
traffic, the load and burst phases, before the attack phase: every request was answered 200,
the gateway counted each received and forwarded and none refused or failed, and each reached
a_hi's side of the router.

No agent runs behind the gateway there: :class:`Receptor` stands in for a_hi's inbox (an
operator's subscriber on the fleet's router, which may hear ``roco/**``; services/spec_check/acl.py)
and takes what the gateway put for a_hi. So a request the gateway refused (its counters,
services/gateway/bridge.py), or a put the router's access control dropped (nothing arrives),
fails the part: :class:`~services.bench.setup_check.SetupRefused`, one line, no figure.
"""

from __future__ import annotations

import queue
import time
from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

from services.bench.setup_check import SetupRefused
from services.runtime import keys
from shared.fipa_codec import DecodeError, decode
from shared.fipa_codec.batch import unpack

__all__ = ["Receptor", "check_legitimate"]

GATEWAY_TROUBLE = ("refused", "internal_errors", "dropped.malformed", "dropped.content", "post_failed")
"""The gateway's counters (services/gateway/bridge.py) that say something it was sent was
refused, raised in it, or was not passed on; ``refused.<reason>`` beside ``refused`` says why."""


class Receptor:
    """Every communicate the gateway puts for ``receiver`` on the router ``session`` reaches
    (a zenoh.Session allowed to hear ``roco/fipa/**``), by conversation-id, from construction
    until :meth:`close`."""

    def __init__(self, session: Any, receiver: str = "a_hi") -> None:
        self.receiver = receiver
        self._got: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()
        self.conversations: Counter[str] = Counter()
        self.undecodable = 0
        self._sub = session.declare_subscriber(
            keys.FIPA_ALL, lambda s: self._got.put((str(s.key_expr), s.payload.to_bytes()))
        )

    def _take(self, key: str, payload: bytes) -> None:
        try:
            if keys.parse_fipa_key(key).receiver != self.receiver:
                return
        except ValueError:
            return
        for one in unpack(payload):  # a batch: each communicate
            try:
                self.conversations[decode(one).conversation_id or ""] += 1
            except DecodeError:
                self.undecodable += 1

    def wait_for(self, conversations: Iterable[str], timeout: float) -> set[str]:
        """Take what arrived until every one of ``conversations`` did or ``timeout`` s passed;
        the ones that did not arrive."""
        missing = set(conversations)
        deadline = time.monotonic() + timeout
        while True:
            missing -= self.conversations.keys()
            left = deadline - time.monotonic()
            if not missing or left <= 0:
                return missing
            try:
                self._take(*self._got.get(timeout=left))
            except queue.Empty:
                continue

    def close(self) -> None:
        self._sub.undeclare()


def check_legitimate(
    statuses: Mapping[int, int],
    counters: Mapping[str, int],
    sent: Iterable[str],
    receptor: Receptor,
    timeout: float = 10.0,
) -> None:
    """Raise SetupRefused (one line) unless the ``sent`` requests (their conversation-ids, one
    request each) were all answered 200 (``statuses``: status → how many posts got it; 0: no
    answer), the gateway's ``counters`` (asked after them) count each received and forwarded and
    none of :data:`GATEWAY_TROUBLE`, and ``receptor`` took each within ``timeout`` s, once."""
    conversations = list(sent)
    n = len(conversations)
    problems = [
        *_answers(statuses, n),
        *_counted(counters, n),
        *_delivered(receptor, conversations, timeout),
    ]
    if problems:
        raise SetupRefused("the gateway's load and burst: " + "; ".join(problems))


def _answers(statuses: Mapping[int, int], n: int) -> list[str]:
    """What is wrong with the HTTP answers to ``n`` posts (``statuses``: status → count)."""
    answered = statuses.get(200, 0)
    if answered == n and sum(statuses.values()) == n:
        return []
    told = ", ".join(f"{k or 'none'}: {v}" for k, v in sorted(statuses.items()))
    return [f"{answered} of {n} requests answered 200 ({told})"]


def _counted(counters: Mapping[str, int], n: int) -> list[str]:
    """What is wrong with the gateway's counters after ``n`` legitimate requests."""
    if not counters:
        return ["no counters from the gateway"]
    wrong = [
        f"the gateway {name} {counters.get(name, 0)} of {n}"
        for name in ("received", "forwarded")
        if counters.get(name, 0) != n
    ]
    bad = {
        k: v for k, v in sorted(counters.items()) if v and (k in GATEWAY_TROUBLE or k.startswith("refused."))
    }
    if bad:
        wrong.append("the gateway counted " + ", ".join(f"{k} {v}" for k, v in bad.items()))
    return wrong


def _delivered(receptor: Receptor, conversations: list[str], timeout: float) -> list[str]:
    """What is wrong with what ``receptor`` took of ``conversations`` within ``timeout`` s."""
    wrong = []
    missing = receptor.wait_for(conversations, timeout)
    if missing:
        wrong.append(
            f"{len(missing)} of {len(conversations)} never reached {receptor.receiver} (e.g. {min(missing)})"
        )
    twice = sorted(c for c, k in receptor.conversations.items() if k > 1)
    if twice:
        wrong.append(f"{len(twice)} reached {receptor.receiver} more than once (e.g. {twice[0]})")
    if receptor.undecodable:
        wrong.append(f"{receptor.undecodable} communicates to {receptor.receiver} not decodable")
    return wrong
