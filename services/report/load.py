"""Reading a run folder tolerantly: every problem becomes a note, never an exception
(except a missing folder).

Sources: ``run.json`` (:class:`RunInfo`), ``traffic.jsonl`` (:class:`TrafficRecord` per line)
and ``traffic.msgpack`` (raw communicates, paired with their records by recorder incarnation
and seq, the record's integrity checked first: services/recorder/integrity.py).
"""

from __future__ import annotations

import dataclasses
import errno
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from services.recorder import integrity
from services.recorder.record import TRAFFIC_JSONL, TRAFFIC_RAW, RecordKey, TrafficRecord, read_payloads
from services.runtime.dedup import wire_digest
from services.runtime.run_folder import RUN_INFO, RunInfo, is_bag_folder, read_run_info
from services.spec.model import SpecError
from services.spec.terms import load_spec_terms
from shared.fipa_codec import Communicate
from shared.fipa_codec.languages import ContentError, decode_content

_record_decoder = msgspec.json.Decoder(TrafficRecord)


@dataclass(frozen=True)
class Message:
    """One recorded communicate: its record ``rec``, arrival ``t`` in s since run start, the
    decoded communicate ``comm`` (None: no or undecodable payload), its decoded content term
    ``content`` (None: no content or not decodable), and ``copy_of``: the ``seq`` of the
    earlier record of the same bytes on the same key when this one is a copy of it (None when
    it is not). A copy is the same communicate sent again: the runtime retransmits a
    communicate byte for byte until it is answered, and publishes its answers again for a copy
    it receives (services/runtime/dedup.py); the network may duplicate one too."""

    rec: TrafficRecord
    t: float
    comm: Communicate | None = None
    content: msgspec.Struct | None = None
    copy_of: int | None = None

    @property
    def channel(self) -> str:
        return self.rec.channel

    @property
    def sender(self) -> str:
        return self.rec.sender

    @property
    def performative(self) -> str:
        return self.rec.performative

    @property
    def conversation(self) -> str | None:
        return self.rec.conversation_id

    def is_(self, channel: str, sender: str | None = None, *performatives: str) -> bool:
        """True when on ``channel``, from ``sender`` (None: anyone), with one of
        ``performatives`` (none given: any)."""
        return (
            self.rec.channel == channel
            and (sender is None or self.rec.sender == sender)
            and (not performatives or self.rec.performative in performatives)
        )


@dataclass
class RunData:
    """A run folder as read: ``info`` (None if run.json is missing or corrupt), ``t0`` the
    run start (POSIX s), ``messages`` in the order they crossed Zenoh, ``integrity`` of the
    traffic record (checked before anything else reads it), ``notes`` on what went wrong."""

    run_dir: Path
    info: RunInfo | None
    t0: float
    messages: list[Message]
    notes: list[str] = field(default_factory=list)
    integrity: integrity.Integrity = field(default_factory=integrity.Integrity)


def load_run(run_dir: Path) -> RunData:
    """Read ``run_dir``. Raises FileNotFoundError (naming the path) when it is not a folder;
    anything else missing or corrupt is noted and skipped."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise FileNotFoundError(errno.ENOENT, "run folder not found", str(run_dir))
    notes: list[str] = []
    info, records, payloads, raw_present = _read_sources(run_dir, notes)
    if info is not None and info.started > 0:
        t0 = info.started
    elif records:
        t0 = min(r.t for r in records)
        notes.append("run start unknown (no run.json `started`): times count from the first record")
    else:
        t0 = 0.0
    checked, comms = integrity.check(records, payloads if raw_present else [])
    if raw_present and not checked.intact:
        notes.insert(0, f"traffic record {checked.summary()}")
    messages = _decode_all(records, comms, t0, notes)
    messages.sort(key=lambda m: (m.rec.t, m.rec.seq))
    _mark_copies(messages, dict(payloads) if raw_present else {})
    return RunData(run_dir, info, t0, messages, notes, checked)


def _mark_copies(messages: list[Message], payloads: dict[RecordKey, bytes]) -> None:
    """Set ``copy_of`` of every message whose bytes on its key came earlier (in ``messages``'
    order): the first of them is the communicate, the others its copies."""
    first: dict[bytes, int] = {}
    for i, m in enumerate(messages):
        payload = payloads.get(m.rec.ref) if m.comm is not None else None
        if payload is None:
            continue
        d = wire_digest(m.rec.key, payload)
        if d in first:
            messages[i] = dataclasses.replace(m, copy_of=first[d])
        else:
            first[d] = m.rec.seq


def _read_sources(
    run_dir: Path, notes: list[str]
) -> tuple[RunInfo | None, list[TrafficRecord], list[tuple[RecordKey, bytes]], bool]:
    """run.json, the records, the payloads and whether a raw stream was there: from the run
    folder's files, or from the /roco/traffic of a rosbag2 folder of roco export."""
    if is_bag_folder(run_dir):
        return (*_read_bag(run_dir, notes), True)
    info = _read_info(run_dir, notes)
    records = _read_records(run_dir, notes)
    payloads = _read_raw(run_dir, notes, expect=bool(records))
    return info, records, payloads, (run_dir / TRAFFIC_RAW).exists()


def _read_bag(
    run_dir: Path, notes: list[str]
) -> tuple[RunInfo | None, list[TrafficRecord], list[tuple[RecordKey, bytes]]]:
    """run.json, records and payloads of a bag folder (services/ros2/bag.py); its problems as
    notes."""
    from services.ros2.bag import BagError, read_bag
    from services.ros2.messages import MissingExtra

    try:
        bag = read_bag(run_dir)
    except (BagError, MissingExtra) as exc:
        notes.append(str(exc))
        return None, [], []
    notes.extend(bag.notes)
    return bag.info, bag.records, bag.payloads


def _read_info(run_dir: Path, notes: list[str]) -> RunInfo | None:
    try:
        return read_run_info(run_dir)
    except FileNotFoundError:
        notes.append(f"no {RUN_INFO}: command, outcome and wall times come from the traffic only")
    except (msgspec.DecodeError, OSError) as exc:
        notes.append(f"{RUN_INFO} unreadable ({_first_line(exc)}): ignored")
    return None


def _read_records(run_dir: Path, notes: list[str]) -> list[TrafficRecord]:
    path = run_dir / TRAFFIC_JSONL
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        notes.append(f"no traffic record ({TRAFFIC_JSONL} missing): no communicates to report")
        return []
    except OSError as exc:
        notes.append(f"{TRAFFIC_JSONL} unreadable ({_first_line(exc)})")
        return []
    records: list[TrafficRecord] = []
    bad: list[int] = []
    first_error = ""
    for lineno, line in enumerate(data.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            records.append(_record_decoder.decode(line))
        except msgspec.DecodeError as exc:
            bad.append(lineno)
            first_error = first_error or _first_line(exc)
    if bad:
        notes.append(
            f"{TRAFFIC_JSONL}: {len(bad)} corrupt line(s) skipped ({_listing('line', bad)}; "
            f"first error: {first_error})"
        )
    if not records:
        notes.append(f"{TRAFFIC_JSONL} holds no communicates")
    return records


def _read_raw(run_dir: Path, notes: list[str], expect: bool) -> list[tuple[RecordKey, bytes]]:
    if not (run_dir / TRAFFIC_RAW).exists():
        if expect:
            notes.append(f"no {TRAFFIC_RAW}: contents not decoded, content-based events missing")
        return []
    out: list[tuple[RecordKey, bytes]] = []
    try:
        out.extend(read_payloads(run_dir))
    except ValueError as exc:  # msgspec.DecodeError is a ValueError
        notes.append(f"{TRAFFIC_RAW} corrupt after {len(out)} payload(s) ({_first_line(exc)}): rest ignored")
    return out


def _decode_all(
    records: list[TrafficRecord],
    comms: dict[RecordKey, Communicate | None],
    t0: float,
    notes: list[str],
) -> list[Message]:
    """One :class:`Message` per record, with the communicate it was paired with (none when it
    was not: see the integrity) and its content decoded in its language (the specification's
    agents' own terms registered first: services/spec/terms.py)."""
    messages: list[Message] = []
    bad_content: list[int] = []
    try:
        load_spec_terms()  # the specification's agents' own terms (services/spec/terms.py)
    except SpecError as exc:
        notes.append(f"agents' own content terms not registered: {exc}")
    for rec in records:
        comm = comms.get(rec.ref)
        content: msgspec.Struct | None = None
        if comm is not None and comm.content and comm.language is not None:  # else a reason in words
            try:
                content = decode_content(comm.language, comm.content)
            except ContentError:
                bad_content.append(rec.seq)
        messages.append(Message(rec, rec.t - t0, comm, content))
    if bad_content:
        notes.append(
            f"{len(bad_content)} content(s) not decodable in their language ({_listing('seq', bad_content)})"
        )
    return messages


def _listing(word: str, items: Iterable[int], limit: int = 5) -> str:
    items = list(items)
    shown = ", ".join(str(i) for i in items[:limit])
    more = f", … ({len(items)} in all)" if len(items) > limit else ""
    return f"{word} {shown}{more}"


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
