"""Is a run's traffic record whole? Pairing, gaps by sequence number, duplicates (docs/recovery.md).

Every reader of a run folder (the report, ``roco spec verify``, the chaos verdict) checks this
first and says what it found, so that nobody reads an answer as the reply to the wrong request:

- **pairing** — each record has exactly one payload with the same
  :class:`~services.recorder.record.RecordKey` (recorder incarnation, seq) and that payload is
  the communicate the record describes (same size, sender, performative and
  conversation-id); a record or payload without its partner, a key written twice (possible only
  in runs recorded before incarnations existed) or a payload that does not match is counted and
  left unpaired, never guessed;
- **gaps** — each Zenoh publisher numbers its communicates 0, 1, 2, … (zenoh-ext advanced
  publisher, services/runtime/transport.py): a number below the highest one recorded that is not
  in the record is a communicate the record lost;
- **duplicates** — the same publisher and sequence number recorded twice.

``late`` counts the communicates a restarted recorder recovered from the publishers' caches.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from services.recorder.record import RecordKey, TrafficRecord
from shared.fipa_codec import Communicate, DecodeError, decode


@dataclass
class Gap:
    """Sequence numbers ``first``..``last`` (inclusive) of the publisher ``source`` on ``key``
    that are not in the record."""

    source: str
    key: str
    first: int
    last: int

    @property
    def count(self) -> int:
        return self.last - self.first + 1

    def __str__(self) -> str:
        which = f"sn {self.first}" if self.first == self.last else f"sn {self.first}–{self.last}"
        return f"{self.key} ({which}, publisher {self.source})"


@dataclass
class Integrity:
    """What :func:`check` found. Keys are (incarnation, seq); ``incarnations`` lists the
    recorder incarnations in the order they first wrote."""

    records: int = 0
    payloads: int = 0
    paired: int = 0
    incarnations: list[str] = field(default_factory=list)
    without_payload: list[RecordKey] = field(default_factory=list)
    without_record: list[RecordKey] = field(default_factory=list)
    ambiguous: list[RecordKey] = field(default_factory=list)
    mismatched: list[RecordKey] = field(default_factory=list)
    gaps: list[Gap] = field(default_factory=list)
    duplicates: list[str] = field(default_factory=list)
    late: int = 0

    @property
    def lost(self) -> int:
        """Communicates missing from the record by their publishers' sequence numbers."""
        return sum(g.count for g in self.gaps)

    @property
    def unpaired(self) -> int:
        return (
            len(self.without_payload) + len(self.without_record) + len(self.ambiguous) + len(self.mismatched)
        )

    @property
    def intact(self) -> bool:
        """Every record paired with its own payload, nothing lost, nothing twice."""
        return self.unpaired == 0 and not self.gaps and not self.duplicates

    def summary(self) -> str:
        """One line: ``intact: 279 communicates, …`` or ``NOT intact: …`` (:meth:`detail`)."""
        return f"{'intact' if self.intact else 'NOT intact'}: {self.detail()}"

    def detail(self) -> str:
        """``279 communicates, 279 paired, 2 recorder incarnations, 37 recovered late``, then
        what is wrong (:meth:`problems`)."""
        parts = [f"{self.records} communicates", f"{self.paired} paired"]
        if len(self.incarnations) > 1:
            parts.append(f"{len(self.incarnations)} recorder incarnations")
        if self.late:
            parts.append(f"{self.late} recovered late")
        return ", ".join(parts) + "".join(f"; {p}" for p in self.problems())

    def problems(self) -> list[str]:
        """What is wrong, one phrase per kind (empty when intact)."""
        out = []
        for what, ks in (
            ("record(s) without payload", self.without_payload),
            ("payload(s) without record", self.without_record),
            ("key(s) written twice, left unpaired", self.ambiguous),
            ("payload(s) not the communicate their record describes", self.mismatched),
        ):
            if ks:
                out.append(f"{len(ks)} {what} ({_keys(ks)})")
        if self.gaps:
            out.append(f"{self.lost} communicate(s) lost: " + "; ".join(str(g) for g in self.gaps[:3]))
        if self.duplicates:
            out.append(f"{len(self.duplicates)} recorded twice ({', '.join(self.duplicates[:3])})")
        return out


def _keys(ks: Sequence[RecordKey], limit: int = 3) -> str:
    shown = ", ".join(f"{k.incarnation or '-'}/{k.seq}" for k in ks[:limit])
    return shown + (f", … {len(ks)} in all" if len(ks) > limit else "")


def _by_key(
    payloads: Iterable[tuple[RecordKey, bytes]], result: Integrity
) -> tuple[dict[RecordKey, bytes], set[RecordKey]]:
    """The raw payloads by record key (the last of a key), counted in ``result``, and the keys
    that come more than once."""
    by_key: dict[RecordKey, bytes] = {}
    twice: set[RecordKey] = set()
    for key, payload in payloads:
        result.payloads += 1
        if key in by_key:
            twice.add(key)
        by_key[key] = payload
    return by_key, twice


def _pair(
    rec: TrafficRecord,
    by_key: dict[RecordKey, bytes],
    twice: set[RecordKey],
    result: Integrity,
    paired: dict[RecordKey, Communicate | None],
) -> None:
    """Pair ``rec`` with its payload into ``paired``, or note in ``result`` why not: its key is
    ambiguous (twice), it has no payload, or the payload does not match it."""
    key = rec.ref
    if key in twice:
        if key not in result.ambiguous:
            result.ambiguous.append(key)
        return
    raw = by_key.get(key)
    if raw is None:
        result.without_payload.append(key)
        return
    ok, comm = _matches(rec, raw)
    if not ok:
        result.mismatched.append(key)
        return
    paired[key] = comm


def check(
    records: Sequence[TrafficRecord], payloads: Iterable[tuple[RecordKey, bytes]]
) -> tuple[Integrity, dict[RecordKey, Communicate | None]]:
    """Check ``records`` against ``payloads`` (the raw stream, in order). Returns the
    integrity and, for each record paired with its own payload, the decoded communicate (None
    for a payload the record itself calls ``malformed``)."""
    result = Integrity(records=len(records))
    by_key, twice = _by_key(payloads, result)
    rec_count = Counter(r.ref for r in records)
    twice |= {k for k, n in rec_count.items() if n > 1}
    paired: dict[RecordKey, Communicate | None] = {}
    for rec in records:
        if rec.incarnation not in result.incarnations:
            result.incarnations.append(rec.incarnation)
        result.late += rec.late
        _pair(rec, by_key, twice, result, paired)
    result.paired = len(paired)
    result.without_record = [k for k in by_key if k not in rec_count]
    _sequences(records, result)
    return result, paired


def _matches(rec: TrafficRecord, raw: bytes) -> tuple[bool, Communicate | None]:
    if len(raw) != rec.size:
        return False, None
    try:
        comm = decode(raw)
    except DecodeError:
        return rec.performative == "malformed", None
    same = (
        comm.performative.value == rec.performative
        and comm.conversation_id == rec.conversation_id
        and (comm.sender.name if comm.sender else rec.sender) == rec.sender
    )
    return same, comm


def _sequences(records: Sequence[TrafficRecord], result: Integrity) -> None:
    seen: dict[str, Counter[int]] = defaultdict(Counter)
    parts: dict[str, Counter[tuple[int, int]]] = defaultdict(Counter)  # (sn, part): batches
    key_of: dict[str, str] = {}
    for rec in records:
        if rec.source is None or rec.sn is None:  # a plain put: nothing to check gaps by
            continue
        seen[rec.source][rec.sn] += 1
        parts[rec.source][(rec.sn, rec.part)] += 1
        key_of[rec.source] = rec.key
    for source, sns in seen.items():
        result.duplicates += [
            f"{key_of[source]} sn {sn}" + (f" part {part}" if part else "")
            for (sn, part), n in sorted(parts[source].items())
            if n > 1
        ]
        result.gaps += _gaps(source, key_of[source], sns)


def _gaps(source: str, key: str, sns: Counter[int]) -> list[Gap]:
    """The runs of sequence numbers missing from ``sns`` (from 0 to the highest), of the
    publisher ``source`` on ``key``."""
    gaps: list[Gap] = []
    start = None
    for sn in range(max(sns) + 1):
        if sn not in sns and start is None:
            start = sn
        elif sn in sns and start is not None:
            gaps.append(Gap(source, key, start, sn - 1))
            start = None
    return gaps
