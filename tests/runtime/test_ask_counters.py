"""`ask_counters` (services/runtime/counters.py) asks again while an agent has not answered: an
ask lost while the agent's session reconnected after a router restart still gets its counters."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import msgspec
import pytest

from services.runtime import counters, keys
from services.runtime.counters import CountersReport, ask_counters
from tests.support.zenoh_sample import sample


@dataclass
class _Sub:
    def undeclare(self) -> None:
        pass


@dataclass
class _Session:
    """A session on which the first ``lost`` asks reach nobody; each later one is answered by
    every agent in ``agents``, on the caller's thread."""

    agents: tuple[str, ...]
    lost: int
    asks: int = 0
    on_answer: Callable[[Any], None] | None = field(default=None)

    def declare_subscriber(self, key: str, callback: Callable[[Any], None]) -> _Sub:
        assert key == keys.COUNTERS_ALL
        self.on_answer = callback
        return _Sub()

    def put(self, key: str, payload: bytes) -> None:
        assert key == keys.COUNTERS_ASK and self.on_answer is not None
        self.asks += 1
        if self.asks <= self.lost:
            return
        for a in self.agents:
            report = CountersReport(agent=a, time=0.0, counters={"handler_errors": 0})
            self.on_answer(sample(msgspec.json.encode(report)))


def test_an_ask_lost_is_asked_again_until_every_agent_answered(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(counters, "ASK_AGAIN_S", 0.05)
    session = _Session(("a_hi", "ag_ex"), lost=2)
    got = ask_counters(session, ["a_hi", "ag_ex"], timeout=5.0)
    assert set(got) == {"a_hi", "ag_ex"} and session.asks == 3


def test_an_agent_that_never_answers_is_absent_after_the_timeout(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(counters, "ASK_AGAIN_S", 0.05)
    session = _Session(("a_hi",), lost=0)
    got = ask_counters(session, ["a_hi", "ag_ex"], timeout=0.3)
    assert set(got) == {"a_hi"} and session.asks >= 2
