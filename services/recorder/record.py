"""The traffic record: one row per communicate seen crossing Zenoh (docs/recovery.md, "The traffic
record across recorder and router faults").

A run folder holds ``traffic.jsonl`` (one :class:`TrafficRecord` per line, JSON, in the order
written) and ``traffic.msgpack`` (the same communicates' raw msgpack payloads, so that content
can be decoded later: a stream of msgpack ``bin`` values, each holding one self-contained
:class:`RawEntry` — payload, key, times and source — from which its record can be made again).
A record and its payload belong together when their :class:`RecordKey` — the recorder
incarnation that wrote them and the index it gave — is the same: a restarted recorder appends
to both files under a new incarnation, so no reader can pair one incarnation's metadata with
another's bytes. The recorder writes an entry's payload before its record, so a
recorder killed in between leaves a payload without its record, which the next incarnation
writes (:func:`repair`). Runs written before incarnations existed hold ``[seq, payload]``
arrays (incarnation ``""``); they still read, and a key written twice there is ambiguous, so it
is left unpaired (:mod:`services.recorder.integrity`), never guessed.

When faults were injected (docs/faults.md), ``faults.jsonl`` holds one
:class:`~services.runtime.faults.FaultEvent` per line, in arrival order.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import msgspec

from services.runtime import keys
from services.runtime.faults import FaultEvent
from services.runtime.run_folder import TRAFFIC_JSONL
from services.runtime.transport import Arrival
from shared.fipa_codec import DecodeError, decode

TRAFFIC_RAW = "traffic.msgpack"
FAULTS_JSONL = "faults.jsonl"
LINK_JSONL = "link.jsonl"
"""The run folder's record of the link between two hosts (services/hosts/link.py writes it): one
JSON object per line, ``{"t": POSIX s, "event": "shaping" | "down" | "up" | "counters", …}``."""
HOSTS_JSON = "hosts.json"
"""A two-host run's hosts (services/hosts/fleet.py writes it): ``{"hosts": {"brain" | "robot":
{"processes": [...], "netns", "link_addr", "link_dev"}}, "operator_endpoint", "mesh",
"lease_ms"}``."""
LINK_BYTES_JSONL = "link_bytes.jsonl"
"""The bytes the routers' link carried, per second and direction, as the relay between the two
hosts forwarded them (services/hosts/relay.py ``--count``): ``{"t": POSIX s, "up": robot → brain,
"down": brain → robot}`` per line."""


class RecordKey(NamedTuple):
    """What ties a record to its payload: the recorder ``incarnation`` that wrote both and the
    ``seq`` it gave them."""

    incarnation: str
    seq: int


class TrafficRecord(msgspec.Struct, frozen=True, kw_only=True):
    """Metadata of one communicate.

    seq: index (0-based) in this run's record, counted on across recorder restarts;
    incarnation: the recorder process that wrote it (a random id per start; ``""`` in records
    written before incarnations existed); t: when it crossed Zenoh (POSIX s): its arrival at the
    recorder, or for a ``late`` record the time its publisher stamped on it; size: payload bytes
    on the wire; channel: C1..C8; sender, receivers: agent names; performative, protocol,
    conversation_id, language, ontology: as in the communicate (FIPA SC00061); key: the Zenoh
    key expression it was published on.

    source, sn: the Zenoh publisher (``<session id>:<entity id>``) and its sequence number
    (0, 1, 2, … per publisher: a number missing from the record is a communicate lost to it;
    zenoh-ext advanced publisher, docs/recovery.md); None for a put that carried none.
    t_sent: the publisher's timestamp (its session's hybrid logical clock, POSIX s), None when
    it carried none. late: sent before this recorder incarnation listened, and recovered from
    the publisher's cache when it started (the recorder was down or restarting).

    sender is the sender the communicate claims (its ``:sender`` parameter; the key's sender
    when it does not decode); key_sender the one its key names (``roco/fipa/C/<sender>/R``):
    with access control on, the identity that authenticated and put it, since the router lets
    only that identity put on such a key (docs/security.md). The two differ for a spoof the
    router let through (an agent posing as another on its own key; its receiver answers
    not-understood, ``rejected.sender_mismatch``); a spoof on another's key never reaches the
    record: the router refuses it and names it in ``refusals.jsonl``. None in records written
    before this field existed, and for a key that is not a communicate key.
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
    incarnation: str = ""
    source: str | None = None
    sn: int | None = None
    t_sent: float | None = None
    late: bool = False
    key_sender: str | None = None
    part: int = 0

    @property
    def ref(self) -> RecordKey:
        """The key of this record's payload in the raw stream."""
        return RecordKey(self.incarnation, self.seq)


_rec_decoder = msgspec.json.Decoder(TrafficRecord)


def record_of(entry: RawEntry) -> TrafficRecord:
    """The record of one raw entry: its communicate's parameters (FIPA SC00061) read from the
    payload, the channel from the key (``roco/fipa/<C>/<sender>/<receiver>``, else ``?``). A
    payload that is not a communicate is recorded with performative ``malformed`` and the key's
    sender and receiver."""
    a = entry.arrival
    key_sender: str | None
    try:
        channel, sender, receiver = keys.parse_fipa_key(a.key)
        key_sender = sender
    except ValueError:
        channel, sender, receiver = "?", "?", "?"
        key_sender = None
    receivers: tuple[str, ...] = (receiver,)
    performative = "malformed"
    protocol = conversation_id = language = ontology = None
    try:
        msg = decode(a.payload)
    except DecodeError:
        pass
    else:
        sender = msg.sender.name if msg.sender else sender
        receivers = tuple(r.name for r in msg.receiver) or receivers
        performative = msg.performative.value
        protocol, conversation_id = msg.protocol, msg.conversation_id
        language, ontology = msg.language, msg.ontology
    return TrafficRecord(
        seq=entry.seq,
        t=a.t,
        size=len(a.payload),
        channel=channel,
        sender=sender,
        receivers=receivers,
        performative=performative,
        protocol=protocol,
        conversation_id=conversation_id,
        language=language,
        ontology=ontology,
        key=a.key,
        incarnation=entry.incarnation,
        source=a.source,
        sn=a.sn,
        t_sent=a.t_sent,
        late=a.late,
        key_sender=key_sender,
        part=a.part,
    )


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


class RawEntry(msgspec.Struct, frozen=True, array_like=True):
    """One communicate in the raw stream, self-contained: the recorder ``incarnation`` and
    ``seq`` that wrote it and the ``arrival`` as the recorder's subscriber saw it (payload, key,
    times, publisher and sequence number: :class:`~services.runtime.transport.Arrival`), from
    which its :class:`TrafficRecord` is made again (:func:`record_of`)."""

    incarnation: str
    seq: int
    arrival: Arrival

    @property
    def ref(self) -> RecordKey:
        return RecordKey(self.incarnation, self.seq)


_raw_encoder = msgspec.msgpack.Encoder()
_raw_decoder = msgspec.msgpack.Decoder(RawEntry)
_BIN_WIDTH = {0xC4: 1, 0xC5: 2, 0xC6: 4}
"""Type byte of a msgpack bin → width of its length field (msgpack spec, "bin format family")."""
_old_decoder: msgspec.msgpack.Decoder[tuple[int, bytes]] = msgspec.msgpack.Decoder(tuple[int, bytes])


def encode_entry(entry: RawEntry) -> bytes:
    """One element of the raw stream: ``entry`` in msgpack, wrapped in a msgpack ``bin``."""
    return _raw_encoder.encode(_raw_encoder.encode(entry))  # bytes encode as a msgpack bin


def read_entries(run_dir: Path) -> Iterator[tuple[RawEntry | None, RecordKey, bytes, int]]:
    """The raw stream of ``run_dir`` in the order written, as (entry, key, payload, end offset)
    tuples; ``entry`` is None for a ``[seq, payload]`` pair of an older run (incarnation
    ``""``). Nothing when the file is missing. Raises ValueError (naming the byte offset) where
    the stream is corrupt or truncated; the elements before it have been yielded."""
    path = run_dir / TRAFFIC_RAW
    if not path.exists():
        return
    data = path.read_bytes()
    pos = 0
    while pos < len(data):
        start, end = _element(data, pos)
        try:
            if data[pos] == 0x92:
                seq, payload = _old_decoder.decode(data[pos:end])
                yield None, RecordKey("", seq), payload, end
            else:
                entry = _raw_decoder.decode(data[start:end])
                yield entry, entry.ref, entry.arrival.payload, end
        except (msgspec.DecodeError, msgspec.ValidationError) as exc:
            raise ValueError(f"corrupt raw traffic stream at byte {pos}: {exc}") from None
        pos = end


def read_payloads(run_dir: Path) -> Iterator[tuple[RecordKey, bytes]]:
    """(key, raw msgpack communicate) pairs of ``run_dir``'s raw stream, in the order written
    (:func:`read_entries`; same errors)."""
    for _, key, payload, _ in read_entries(run_dir):
        yield key, payload


def _element(data: bytes, pos: int) -> tuple[int, int]:
    """(start of content, end) of the raw-stream element at ``pos``: a ``bin`` wrapping a
    :class:`RawEntry`, or an older run's ``[seq, payload]`` array (content from ``pos``)."""
    t = data[pos]
    start = pos
    try:
        if t == 0x92:
            return pos, _old_pair_end(data, pos)
        width = _BIN_WIDTH.get(t)
        if width is None:
            raise ValueError(f"corrupt raw traffic stream at byte {pos}")
        start = pos + 1 + width
        end = start + int.from_bytes(data[pos + 1 : start], "big")
    except IndexError:
        end = len(data) + 1
    if end > len(data):
        raise ValueError(f"truncated raw traffic stream at byte {pos}")
    return start, end


def _old_pair_end(data: bytes, pos: int) -> int:
    """End of a msgpack ``[int, bin]`` array at ``pos`` (the older raw format, still read)."""
    p = pos + 1
    t = data[p]
    if t <= 0x7F:
        p += 1
    else:
        width = {0xCC: 1, 0xCD: 2, 0xCE: 4, 0xCF: 8}.get(t)
        if width is None:
            raise ValueError(f"corrupt raw traffic stream at byte {p}")
        p += 1 + width
    width = _BIN_WIDTH.get(data[p])
    if width is None:
        raise ValueError(f"corrupt raw traffic stream at byte {p}")
    return p + 1 + width + int.from_bytes(data[p + 1 : p + 1 + width], "big")


class LinkSecond(msgspec.Struct, frozen=True):
    """One second of the link's traffic (:data:`LINK_BYTES_JSONL`): its start ``t`` (POSIX s),
    the bytes ``up`` (robot → brain) and ``down`` (brain → robot)."""

    t: float
    up: int = 0
    down: int = 0


_link_second = msgspec.json.Decoder(LinkSecond)


def read_link_bytes(run_dir: Path) -> list[LinkSecond]:
    """The seconds of ``run_dir/link_bytes.jsonl`` in time order (none when the run had no
    counting relay); lines that do not read are skipped."""
    try:
        lines = (run_dir / LINK_BYTES_JSONL).read_bytes().splitlines()
    except OSError:
        return []
    out = []
    for line in lines:
        try:
            out.append(_link_second.decode(line))
        except (msgspec.DecodeError, msgspec.ValidationError):
            continue
    return sorted(out, key=lambda s: s.t)


MAX_HOSTS_BYTES = 1 << 20
"""A larger ``hosts.json`` is not read (it names a few processes)."""


def read_hosts(run_dir: Path) -> dict[str, str]:
    """The host of each process of a run on several hosts (``hosts.json``: process → host
    name), none for a run on one host, or when the file is too large or not as
    services/hosts/fleet.py writes it."""
    path = run_dir / HOSTS_JSON
    try:
        if path.stat().st_size > MAX_HOSTS_BYTES:
            return {}
        hosts = json.loads(path.read_text())["hosts"]
        return {str(p): str(h) for h, host in hosts.items() for p in host["processes"]}
    except (OSError, ValueError, LookupError, TypeError, AttributeError):
        return {}


def read_link_events(run_dir: Path) -> list[dict[str, object]]:
    """The events of ``run_dir/link.jsonl`` (none when the run had no link between hosts);
    lines that are not JSON objects are skipped."""
    try:
        lines = (run_dir / LINK_JSONL).read_text().splitlines()
    except OSError:
        return []
    out = []
    for line in lines:
        try:
            item = msgspec.json.decode(line)
        except msgspec.DecodeError:
            continue
        if isinstance(item, dict):
            out.append(item)
    return out
