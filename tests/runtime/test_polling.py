"""A receiving thread's adaptive polling (services/runtime/polling.py): quick answers
are caught in the poll, slow ones turn the poll off, the setting is read with a clear error.
The clock and the FIFO are simulated: no test depends on the machine's timing."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from services.fleet.launcher import free_port
from services.runtime.polling import DEFAULT_MAX_POLL_US, ENV_POLL, GROW_START_US, AdaptivePoll, max_poll_us

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class Clock:
    """Simulated time (s); every reading advances it by ``tick`` (a poll's cost)."""

    now: float = 0.0
    tick: float = 1e-6

    def __call__(self) -> float:
        self.now += self.tick
        return self.now


@dataclass
class Fifo:
    """Items that arrive at given simulated times; ``recv`` sleeps (advances the clock) until
    the next one."""

    clock: Clock
    arrivals: deque[tuple[float, str]] = field(default_factory=deque)
    recvs: int = 0

    def try_recv(self) -> str | None:
        if self.arrivals and self.arrivals[0][0] <= self.clock.now:
            return self.arrivals.popleft()[1]
        return None

    def recv(self) -> str:
        self.recvs += 1
        if not self.arrivals:
            raise RuntimeError("closed")
        at, item = self.arrivals.popleft()
        self.clock.now = max(self.clock.now, at)
        return item


def exchange(poll: AdaptivePoll, fifo: Fifo, gap_s: float, n: int) -> list[str]:
    """``n`` items each arriving ``gap_s`` after the previous one was taken (a ping-pong)."""
    got = []
    for i in range(n):
        fifo.arrivals.append((fifo.clock.now + gap_s, f"m{i}"))
        got.append(poll.next(fifo))
    return got


def test_quick_answers_are_caught_in_the_poll_after_the_window_has_grown() -> None:
    clock = Clock()
    fifo = Fifo(clock)
    poll = AdaptivePoll(500.0, clock=clock, yield_=lambda: None)
    got = exchange(poll, fifo, 300e-6, 20)
    assert got == [f"m{i}" for i in range(20)]  # in order, none lost
    # 0 → 50 → 100 → 200 → 400 µs: four sleeps grow the window past the 300 µs gap
    assert poll.slept == 4
    assert poll.polled == 16
    assert fifo.recvs == 4
    assert poll.window_s == pytest.approx(400e-6)


def test_slow_answers_turn_the_poll_off() -> None:
    clock = Clock()
    fifo = Fifo(clock)
    poll = AdaptivePoll(500.0, clock=clock, yield_=lambda: None)
    exchange(poll, fifo, 300e-6, 10)
    assert poll.window_s > 0
    exchange(poll, fifo, 20e-3, 4)  # a peer that answers in 20 ms: the window halves each time
    assert poll.window_s == 0.0
    before = poll.polled
    exchange(poll, fifo, 20e-3, 5)
    assert poll.polled == before  # asleep at once: no poll spent on slow answers
    assert fifo.recvs == poll.slept


def test_an_item_already_waiting_is_taken_without_polling_or_sleeping() -> None:
    clock = Clock()
    fifo = Fifo(clock, deque([(0.0, "a"), (0.0, "b")]))
    yields: list[None] = []
    poll = AdaptivePoll(500.0, clock=clock, yield_=lambda: yields.append(None))
    assert [poll.next(fifo), poll.next(fifo)] == ["a", "b"]
    assert fifo.recvs == 0 and not yields


def test_polling_gives_the_core_away_between_polls() -> None:
    clock = Clock()
    fifo = Fifo(clock)
    yields: list[None] = []
    poll = AdaptivePoll(500.0, clock=clock, yield_=lambda: yields.append(None))
    poll.window_s = 100e-6
    fifo.arrivals.append((clock.now + 50e-6, "x"))
    assert poll.next(fifo) == "x"
    assert poll.polled == 1 and fifo.recvs == 0
    assert len(yields) >= 10


def test_a_zero_maximum_never_polls() -> None:
    clock = Clock()
    fifo = Fifo(clock)
    yields: list[None] = []
    poll = AdaptivePoll(0.0, clock=clock, yield_=lambda: yields.append(None))
    exchange(poll, fifo, 10e-6, 10)
    assert poll.window_s == 0.0 and poll.polled == 0 and not yields


def test_a_closed_fifo_raises_through_the_wait() -> None:
    clock = Clock()
    poll = AdaptivePoll(500.0, clock=clock, yield_=lambda: None)
    with pytest.raises(RuntimeError, match="closed"):
        poll.next(Fifo(clock))


def test_the_maximum_window_is_read_from_the_environment() -> None:
    assert max_poll_us({}) == DEFAULT_MAX_POLL_US
    assert max_poll_us({ENV_POLL: "0"}) == 0.0
    assert max_poll_us({ENV_POLL: " 250 "}) == 250.0
    assert GROW_START_US < DEFAULT_MAX_POLL_US


@pytest.mark.parametrize("bad", ["-1", "fast", "nan", "inf"])
def test_a_malformed_maximum_window_names_the_variable(bad: str) -> None:
    with pytest.raises(ValueError, match=ENV_POLL):
        max_poll_us({ENV_POLL: bad})


@pytest.mark.parametrize(
    ("command", "says"),
    [
        (["services.runtime.main", "a_co"], "roco: agent a_co: "),
        (["services.recorder.recorder"], "roco: recorder: "),
    ],
)
def test_a_process_with_a_malformed_window_exits_2_with_one_line(
    command: list[str], says: str, tmp_path: Path
) -> None:
    env = dict(
        os.environ,
        ROCO_RECEIVE_POLL_US="fast",
        ROCO_ROUTER=f"tcp/127.0.0.1:{free_port()}",
        ROCO_RUN_DIR=str(tmp_path),  # logs there: stderr holds only the one line
    )
    done = subprocess.run(
        [sys.executable, "-m", *command],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{says}ROCO_RECEIVE_POLL_US='fast'"), done.stderr
