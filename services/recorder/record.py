"""The traffic record: one row per communicate seen crossing Zenoh (design.md, "traffic recorder").

A run folder holds ``traffic.jsonl`` (one :class:`TrafficRecord` per line, JSON, in arrival
order) and ``traffic.msgpack`` (the same communicates' raw msgpack payloads, as a msgpack
stream of ``[seq, payload]`` pairs, so that content can be decoded later). When faults were
injected (docs/faults.md), ``faults.jsonl`` holds one
:class:`~services.runtime.faults.FaultEvent` per line, in arrival order.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import msgspec

from services.runtime.faults import FaultEvent

TRAFFIC_JSONL = "traffic.jsonl"
TRAFFIC_RAW = "traffic.msgpack"
FAULTS_JSONL = "faults.jsonl"


class TrafficRecord(msgspec.Struct, frozen=True, kw_only=True):
    """Metadata of one communicate.

    seq: arrival index (0-based) in this record; t: wall time of arrival at the recorder
    (POSIX s); size: payload bytes on the wire; channel: C1..C6; sender, receivers: agent
    names; performative, protocol, conversation_id, language, ontology: as in the communicate
    (FIPA SC00061); key: the Zenoh key expression it was published on.
    """

    seq: int
    t: float
    size: int
    channel: str
    sender: str
    receivers: tuple[str, ...]
    performative: str
    protocol: str | None = None
    conversation_id: str | None = None
    language: str | None = None
    ontology: str | None = None
    key: str = ""


_rec_decoder = msgspec.json.Decoder(TrafficRecord)


def read_records(run_dir: Path) -> list[TrafficRecord]:
    """All records of ``run_dir``; raises FileNotFoundError when it has no traffic record
    and msgspec.DecodeError on a corrupt line (naming nothing else: callers add the path)."""
    lines = (run_dir / TRAFFIC_JSONL).read_bytes().splitlines()
    return [_rec_decoder.decode(line) for line in lines if line.strip()]


_fault_decoder = msgspec.json.Decoder(FaultEvent)


def read_fault_events(run_dir: Path) -> tuple[list[FaultEvent], int]:
    """The fault events of ``run_dir`` (none when it has no ``faults.jsonl``) and the number
    of lines that could not be read."""
    path = run_dir / FAULTS_JSONL
    if not path.exists():
        return [], 0
    events: list[FaultEvent] = []
    bad = 0
    for line in path.read_bytes().splitlines():
        if not line.strip():
            continue
        try:
            events.append(_fault_decoder.decode(line))
        except msgspec.DecodeError:
            bad += 1
    return events, bad


def read_payloads(run_dir: Path) -> Iterator[tuple[int, bytes]]:
    """(seq, raw msgpack communicate) pairs from ``run_dir``'s raw stream, in order."""
    path = run_dir / TRAFFIC_RAW
    if not path.exists():
        return
    unpacker = msgspec.msgpack.Decoder(tuple[int, bytes])
    data = path.read_bytes()
    # The file is a concatenation of msgpack arrays; decode them one by one.
    pos = 0
    while pos < len(data):
        end = _next_end(data, pos)
        yield unpacker.decode(data[pos:end])
        pos = end


def _next_end(data: bytes, pos: int) -> int:
    """End offset of the msgpack array [int, bin] starting at ``pos`` (format of our writer)."""
    b = data[pos]
    if b != 0x92:
        raise ValueError(f"corrupt raw traffic stream at byte {pos}")
    p = pos + 1
    # integer
    t = data[p]
    if t <= 0x7F:
        p += 1
    elif t == 0xCC:
        p += 2
    elif t == 0xCD:
        p += 3
    elif t == 0xCE:
        p += 5
    elif t == 0xCF:
        p += 9
    else:
        raise ValueError(f"corrupt raw traffic stream at byte {p}")
    # bin
    t = data[p]
    if t == 0xC4:
        n = data[p + 1]
        p += 2
    elif t == 0xC5:
        n = int.from_bytes(data[p + 1 : p + 3], "big")
        p += 3
    elif t == 0xC6:
        n = int.from_bytes(data[p + 1 : p + 5], "big")
        p += 5
    else:
        raise ValueError(f"corrupt raw traffic stream at byte {p}")
    return p + n
