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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import msgspec
import zenoh

from services.runtime.faults import (
    ANY_CHANNEL,
    CONTROL_ALL,
    STATE_ALL,
    FaultReport,
    FaultUpdate,
    NetFaults,
    control_key,
)
from services.runtime.session import alive_agents

if TYPE_CHECKING:
    from services.spec.model import SystemSpec


@dataclass(frozen=True)
class NetChange:
    """What `roco fault net` changes of an agent's network faults (None: kept as it is)."""

    delay: float | None
    loss: float | None
    partition: bool | None

    def applied_to(self, now: NetFaults) -> NetFaults:
        return NetFaults(
            delay_s=now.delay_s if self.delay is None else self.delay,
            loss=now.loss if self.loss is None else self.loss,
            partition=now.partition if self.partition is None else self.partition,
        )


def clear_update(target: str | None, system: SystemSpec) -> tuple[FaultUpdate, str | None] | None:
    """The update that clears ``target``'s faults (a channel, '*', an agent; None: every
    fault) in the fault layers of ``system``'s agents, and the agent it goes to (None: every
    agent); None when ``target`` is a service without one."""
    channels = [c.name for c in system.channels]
    if target in system.agent_names:
        return FaultUpdate(clear_services=[target]), target
    if target is None:
        return FaultUpdate(clear_channels=["*"], clear_services=["*"]), None
    if target in (*channels, ANY_CHANNEL):
        return FaultUpdate(clear_channels=[target]), None
    return None


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
