"""Reading the running agents' counters over Zenoh (``roco status``, tests, scripts).

A put on :data:`~services.runtime.keys.COUNTERS_ASK` makes every agent publish
``{"agent": name, "time": POSIX s, "counters": {name: count}}`` (JSON) on
``roco/counters/report/<agent>`` from its own thread, between two steps: an agent busy in a
long step (a_pl planning) answers when the step ends. Counter names: ``received.<act>``,
``sent.<act>``, ``rejected`` (not-understood sent), ``rejected.<reason>``
(services/runtime/limits.py ``REJECT_REASONS``), ``duplicates``, ``retransmitted``, …
"""

from __future__ import annotations

import queue
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import msgspec

from services.runtime import keys
from services.runtime.raised import raised


class CountersReport(msgspec.Struct, frozen=True):
    """One agent's answer: its ``agent`` name, the POSIX ``time`` it was made, its
    ``counters`` and the id of its Zenoh ``session`` (what the traffic record names as the
    ``source`` of its communicates before the ``:``; "" on a transport without one)."""

    agent: str
    time: float
    counters: dict[str, int]
    session: str = ""


_decoder = msgspec.json.Decoder(CountersReport)
COUNTERS_JSON = "counters.json"
"""In a run folder: every agent's last :class:`CountersReport` when the command(s) ended, as
``{agent: report}`` (services/scenario/runner.py)."""


def save_counters(run_dir: Path, reports: dict[str, CountersReport]) -> None:
    """Write ``reports`` to ``run_dir``'s :data:`COUNTERS_JSON`. Raises OSError."""
    (run_dir / COUNTERS_JSON).write_bytes(msgspec.json.encode(reports))


def read_counters(run_dir: Path) -> dict[str, CountersReport]:
    """The reports :func:`save_counters` wrote in ``run_dir``. Raises FileNotFoundError when
    there are none and msgspec.DecodeError when the file is corrupt."""
    data = (run_dir / COUNTERS_JSON).read_bytes()
    return msgspec.json.decode(data, type=dict[str, CountersReport])


ASK_AGAIN_S = 1.0
"""Seconds between the asks of :func:`ask_counters` while some agents have not answered."""


def ask_counters(session: Any, agents: Iterable[str], timeout: float = 2.0) -> dict[str, CountersReport]:
    """Ask every agent for its counters over ``session`` (a :class:`zenoh.Session`); wait up to
    ``timeout`` s for each of ``agents`` to answer, asking again every :data:`ASK_AGAIN_S` while
    some have not (an ask or an answer lost while a session reconnects after a router restart).
    Returns the latest answer by agent (an agent that did not answer in time is absent;
    malformed answers are ignored)."""
    wanted = set(agents)
    answers: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    sub = session.declare_subscriber(keys.COUNTERS_ALL, lambda s: answers.put(s.payload.to_bytes()))
    out: dict[str, CountersReport] = {}
    try:
        session.put(keys.COUNTERS_ASK, b"")  # asked once whatever the timeout (roco status's 0)
        deadline = time.monotonic() + timeout
        ask_at = time.monotonic() + ASK_AGAIN_S
        while not wanted <= out.keys():
            now = time.monotonic()
            if now >= deadline:
                break
            if now >= ask_at:
                session.put(keys.COUNTERS_ASK, b"")
                ask_at = now + ASK_AGAIN_S
            try:
                payload = answers.get(timeout=max(0.0, min(deadline, ask_at) - now))
            except queue.Empty:
                continue
            try:
                report = _decoder.decode(payload)
            except (msgspec.DecodeError, msgspec.ValidationError):
                continue
            out[report.agent] = report
    finally:
        sub.undeclare()
    return out


def rejects(counters: dict[str, int]) -> dict[str, int]:
    """The ``rejected.<reason>`` counters as {reason: count}, largest first."""
    found = {k.split(".", 1)[1]: v for k, v in counters.items() if k.startswith("rejected.") and v}
    return dict(sorted(found.items(), key=lambda kv: (-kv[1], kv[0])))


def summary(counters: dict[str, int]) -> str:
    """One line: communicates received, rejected inputs by reason, duplicates, the notices a_hi
    passed on to the person and dropped (services/agents/human_interface/notices.py) when
    there were any, and what the agent raised (services/runtime/raised.py) when it did
    (``received 812, rejected 10012 (malformed 5000, protocol_state 12), duplicates 3, notices
    4 (2 dropped), handler_errors 2``)."""
    received = sum(v for k, v in counters.items() if k.startswith("received."))
    by_reason = rejects(counters)
    parts = [f"received {received}", f"rejected {sum(by_reason.values())}"]
    if by_reason:
        parts[-1] += " (" + ", ".join(f"{k} {v}" for k, v in by_reason.items()) + ")"
    if counters.get("duplicates"):
        parts.append(f"duplicates {counters['duplicates']}")
    told, dropped = counters.get("notices", 0), counters.get("notices_dropped", 0)
    if told or dropped:
        parts.append(f"notices {told}" + (f" ({dropped} dropped)" if dropped else ""))
    parts += [f"{k} {v}" for k, v in raised(counters).items()]
    return ", ".join(parts)
