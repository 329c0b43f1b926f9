"""Traffic in Rerun: what the traffic recorder logs for every communicate it sees.

Entities (timeline ``wall``: the recorder's arrival time, POSIX s):

- ``traffic/log`` — one ``TextLog`` row per communicate, in FIPA SC00070 string form (human
  form: content as JSON), with ``AnyValues`` sender, receiver, performative, protocol,
  conversation_id, channel, size and seq on the same row;
- ``traffic/size/<C>`` — the communicate's size in bytes (paper Figure 12), one row each;
- ``traffic/bandwidth/<C>`` — kbit/s on the channel over the last ``WINDOW`` s, one row per
  communicate (paper Figure 13);
- ``task/sw_state`` and ``task/step`` — a_ta's L_SW state and current HFSM step (text), from
  its L_SW communicates on C1 (``task/step`` only when the step changes);
- ``graph/agents`` — the agents (nodes) and channels (edges) of the specification (static).
"""

from __future__ import annotations

import collections
import math
from typing import Protocol

import rerun as rr

from services.spec.model import SystemSpec, load, spec_path
from services.viewer.recording import Recording
from shared.fipa_codec import Communicate, DecodeError, decode
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.string_form import to_string

WINDOW = 1.0  # s, the bandwidth window
WALL = "wall"
TRAFFIC_LOG = "traffic/log"
SIZE = "traffic/size"
BANDWIDTH = "traffic/bandwidth"
SW_STATE = "task/sw_state"
STEP = "task/step"
GRAPH = "graph/agents"
GRAPH_RADIUS = 120.0  # graph view units (≈ px at zoom 1)
SW_LEVEL = {"Error": "ERROR", "Replan": "WARN", "Preempted": "WARN"}


def spec_from_env() -> SystemSpec:
    """The specification the processes run with (``ROCO_SPEC``, default the repo's)."""
    return load(spec_path())


def log_graph(stream: rr.RecordingStream, spec: SystemSpec) -> None:
    """The agents and channels of ``spec`` as a graph (static), the agents on a circle of
    radius ``GRAPH_RADIUS`` in the specification's order (fixed positions, so that no two
    labels overlap, which the viewer's force layout let happen)."""
    names = [a.name for a in spec.agents]
    for ch in spec.channels:
        names.extend(e for e in ch.ends if e not in names)
    step = 2.0 * math.pi / max(1, len(names))
    positions = [
        (GRAPH_RADIUS * math.sin(i * step), -GRAPH_RADIUS * math.cos(i * step)) for i in range(len(names))
    ]
    stream.log(GRAPH, rr.GraphNodes(names, labels=names, positions=positions), static=True)
    stream.log(
        GRAPH,
        rr.GraphEdges([ch.ends for ch in spec.channels], graph_type="undirected"),
        static=True,
    )


class TrafficRow(Protocol):
    """What the traffic log reads of one record (the fields of the recorder's
    ``TrafficRecord``, services/recorder/record.py; the viewer does not import the recorder):
    POSIX time ``t``, index ``seq``, payload ``size`` in bytes, ``channel``, ``key``,
    ``sender``, ``receivers``, FIPA ``performative``, ``protocol``, ``conversation_id``."""

    @property
    def t(self) -> float: ...
    @property
    def seq(self) -> int: ...
    @property
    def size(self) -> int: ...
    @property
    def channel(self) -> str: ...
    @property
    def key(self) -> str: ...
    @property
    def sender(self) -> str: ...
    @property
    def receivers(self) -> tuple[str, ...]: ...
    @property
    def performative(self) -> str: ...
    @property
    def protocol(self) -> str | None: ...
    @property
    def conversation_id(self) -> str | None: ...


def _line(msg: Communicate | None, record: TrafficRow) -> tuple[str, str]:
    """The text line of a communicate (None: its payload is malformed) and its level."""
    if msg is None:
        return f"malformed {record.size} B on {record.key}", "WARN"
    try:
        return to_string(msg, human=True), "INFO"
    except ValueError as exc:  # a :protocol, reply-by or user parameter SC00070 cannot carry
        return f"not printable in the string form: {exc}", "WARN"


def _sw_status(msg: Communicate | None) -> SWStatus | None:
    """a_ta's L_SW state that ``msg`` carries, if it carries one."""
    if msg is None or msg.language != "L_SW" or not msg.content:
        return None
    try:
        term = decode_content(msg.language, msg.content)
    except ContentError:  # a malformed L_SW content is the conformance checker's business
        return None
    return term if isinstance(term, SWStatus) else None


class TrafficLogger:
    """Logs communicates (payloads as they crossed Zenoh, with their traffic records) to
    one recording part; keeps the per-channel bandwidth windows and a_ta's last step."""

    def __init__(self, recording: Recording, spec: SystemSpec | None = None) -> None:
        self.stream = recording.stream
        self.spec = spec if spec is not None else spec_from_env()
        self._windows: dict[str, collections.deque[tuple[float, int]]] = collections.defaultdict(
            collections.deque
        )
        self._window_bytes: dict[str, int] = collections.defaultdict(int)
        self._series: set[str] = set()
        self._step: str | None = None
        log_graph(self.stream, self.spec)

    def _channel_series(self, channel: str) -> None:
        if channel in self._series:
            return
        self._series.add(channel)
        self.stream.log(f"{SIZE}/{channel}", rr.SeriesPoints(names=[f"{channel} size [B]"]), static=True)
        self.stream.log(
            f"{BANDWIDTH}/{channel}", rr.SeriesLines(names=[f"{channel} bandwidth [kbit/s]"]), static=True
        )

    def bandwidth(self, channel: str, t: float, size: int) -> float:
        """Add ``size`` bytes at ``t`` to ``channel``'s window; kbit/s over the last WINDOW s."""
        window = self._windows[channel]
        window.append((t, size))
        self._window_bytes[channel] += size
        while window and window[0][0] <= t - WINDOW:
            self._window_bytes[channel] -= window.popleft()[1]
        return self._window_bytes[channel] * 8 / 1000 / WINDOW

    def communicate(self, record: TrafficRow, payload: bytes) -> None:
        """Log one communicate: its text line, size, channel bandwidth, and a_ta's state."""
        s = self.stream
        s.set_time(WALL, timestamp=record.t)
        receiver = ",".join(record.receivers)
        try:
            msg: Communicate | None = decode(payload)
        except DecodeError:
            msg = None
        text, level = _line(msg, record)
        s.log(
            TRAFFIC_LOG,
            rr.TextLog(text, level=level),
            rr.AnyValues(
                seq=record.seq,
                channel=record.channel,
                sender=record.sender,
                receiver=receiver,
                performative=record.performative,
                protocol=record.protocol or "",
                conversation_id=record.conversation_id or "",
                size=record.size,
            ),
        )
        self._channel_series(record.channel)
        s.log(f"{SIZE}/{record.channel}", rr.Scalars(float(record.size)))
        s.log(
            f"{BANDWIDTH}/{record.channel}",
            rr.Scalars(self.bandwidth(record.channel, record.t, record.size)),
        )
        status = _sw_status(msg)
        if status is not None:
            self.sw_status(status)

    def sw_status(self, status: SWStatus) -> None:
        """Log a_ta's L_SW state and, when it changed, its HFSM step (at the current time)."""
        state = status.state.value
        detail = f" plan={status.plan_id}" if status.plan_id else ""
        if status.step:
            detail += f" step={status.step}"
        if status.reason:
            detail += f" reason={status.reason}"
        self.stream.log(SW_STATE, rr.TextLog(state + detail, level=SW_LEVEL.get(state, "INFO")))
        if status.step and status.step != self._step:
            self._step = status.step
            self.stream.log(STEP, rr.TextLog(status.step))
