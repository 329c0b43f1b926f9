"""Message and network faults of running agents, changed over Zenoh: a
:class:`~services.runtime.faults.FaultUpdate` put on ``roco/fault/control/all`` (every agent)
or ``roco/fault/control/<agent>`` (one), answered by each agent that applied it with its
:class:`~services.runtime.faults.FaultReport` on ``roco/fault/state/<agent>``. Works on any
fleet whose router this process reaches (local or compose)."""

from __future__ import annotations

import queue
import time
import uuid
from collections.abc import Collection

import msgspec
import zenoh

from services.runtime.faults import (
    CONTROL_ALL,
    STATE_ALL,
    FaultReport,
    FaultUpdate,
    control_key,
)
from services.runtime.session import alive_agents


def send_update(
    session: zenoh.Session,
    update: FaultUpdate,
    target: str | None = None,
    timeout: float = 5.0,
    *,
    agents: Collection[str],
) -> tuple[dict[str, FaultReport], list[str]]:
    """Put ``update`` for ``target`` (None: every agent) and collect the agents' reports.

    Waits until every agent expected has answered — ``target``, or every one of ``agents``
    (the fleet's specification's) holding a liveliness token — or ``timeout`` s passed.
    Returns the reports by agent and the agents expected that did not answer."""
    request = uuid.uuid4().hex[:12]
    update = msgspec.structs.replace(update, request=request)
    expected = {target} if target is not None else alive_agents(session) & set(agents)
    answers: queue.SimpleQueue[FaultReport] = queue.SimpleQueue()
    dec = msgspec.json.Decoder(FaultReport)

    def on_state(sample: zenoh.Sample) -> None:  # Zenoh thread: enqueue only
        try:
            report = dec.decode(sample.payload.to_bytes())
        except (msgspec.DecodeError, msgspec.ValidationError):
            return
        if report.request == request:
            answers.put(report)

    sub = session.declare_subscriber(STATE_ALL, on_state)
    try:
        session.put(control_key(target) if target is not None else CONTROL_ALL, msgspec.json.encode(update))
        got: dict[str, FaultReport] = {}
        deadline = time.monotonic() + timeout
        while not expected <= set(got):
            left = deadline - time.monotonic()
            if left <= 0:
                break
            try:
                report = answers.get(timeout=left)
            except queue.Empty:
                break
            got[report.agent] = report
        while True:  # answers already in, from agents not expected (partitioned ones)
            try:
                report = answers.get_nowait()
            except queue.Empty:
                break
            got[report.agent] = report
    finally:
        sub.undeclare()
    return got, sorted(expected - set(got))
