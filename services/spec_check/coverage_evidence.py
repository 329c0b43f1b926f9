"""What ``roco spec coverage`` counts from: the communicates and FSM records of run folders and
of a test run's tap folder.

A run folder (services/runtime/run_folder.py) holds the traffic recorder's record
(``traffic.jsonl``, ``traffic.msgpack``: services/report/load.py reads it) and each agent's
FSM record (``fsm/``: services/runtime/fsm_record.py). A tap folder (``ROCO_TAP_DIR``,
services/runtime/tap.py) holds what every bus and transport of a test run put, by group (one
bus, one fleet), and the FSM records of every agent the tests started. Either becomes
:class:`Evidence`: groups of communicates, each group in causal order (an answer after what
it answers: services/recorder/causal.py), within which conversations are followed, and the
FSM records. Copies (the same bytes again on the same key: a retransmission) are left out, as
``roco spec verify`` judges each communicate once.
"""

from __future__ import annotations

import dataclasses
import errno
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from services.recorder.causal import causal_order, send_order
from services.recorder.record import RawEntry, record_of
from services.report.load import Message, load_run
from services.runtime.dedup import wire_digest
from services.runtime.fsm_record import Record, read_records, record_files
from services.runtime.tap import TapEntry, read_tap, tap_files
from services.runtime.transport import Arrival
from shared.fipa_codec import DecodeError, decode
from shared.fipa_codec.languages import ContentError, decode_content

MAX_TAP_BYTES = 2 * 1024 * 1024 * 1024
"""Most bytes of one tap file read (a whole test suite's traffic is ≈ 10² MB)."""


@dataclass
class Evidence:
    """Groups of communicates (each followed on its own, in causal order), FSM records, what
    each source gave (``sources``, one line each) and problems reading them (``notes``)."""

    groups: list[list[Message]] = field(default_factory=list)
    fsm: list[Record] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def communicates(self) -> int:
        return sum(len(g) for g in self.groups)


def _ordered(messages: list[Message]) -> list[Message]:
    """``messages`` without copies, in causal and send order."""
    originals = [m for m in messages if m.copy_of is None]
    return send_order(causal_order(originals)[0])[0]


def _fsm_records(folder: Path, notes: list[str]) -> list[Record]:
    out: list[Record] = []
    for path in record_files(folder):
        try:
            out.extend(read_records(path))
        except (OSError, ValueError) as exc:
            notes.append(f"{path}: not read ({exc})")
    return out


def add_run(evidence: Evidence, run_dir: Path) -> None:
    """Add run folder ``run_dir`` (one group). Raises FileNotFoundError when it is not a
    folder; what cannot be read in it becomes a note."""
    data = load_run(run_dir)
    messages = _ordered(data.messages)
    evidence.groups.append(messages)
    records = _fsm_records(run_dir, evidence.notes)
    evidence.fsm.extend(records)
    evidence.notes.extend(f"{run_dir}: {n}" for n in data.notes if not n.startswith("run start unknown"))
    if not records:
        evidence.notes.append(
            f"{run_dir}: no FSM record (fsm/): agents record their FSM's transitions in runs made since "
            "roco spec coverage exists; its FSMs count as never entered"
        )
    evidence.sources.append(f"{run_dir}: {len(messages)} communicates, {len(records)} FSM records")


def _message(entry: TapEntry, seq: int) -> Message:
    """One tapped communicate as a recorded one (services/report/load.py ``Message``)."""
    rec = record_of(RawEntry(entry.group, seq, Arrival(entry.t, entry.key, entry.payload)))
    try:
        comm = decode(entry.payload)
    except DecodeError:
        return Message(rec, entry.t)
    content = None
    if comm.language is not None and comm.content:
        try:
            content = decode_content(comm.language, comm.content)
        except ContentError:
            content = None
    return Message(rec, entry.t, comm, content)


def _marked(messages: list[Message], entries: list[TapEntry]) -> list[Message]:
    """``messages`` with ``copy_of`` set on each whose bytes on its key came earlier."""
    first: dict[bytes, int] = {}
    out = []
    for m, e in zip(messages, entries, strict=True):
        digest = wire_digest(e.key, e.payload)
        seen = first.setdefault(digest, m.rec.seq)
        out.append(m if seen == m.rec.seq else dataclasses.replace(m, copy_of=seen))
    return out


def add_tap(evidence: Evidence, folder: Path) -> None:
    """Add tap folder ``folder`` (one group per bus or fleet in it). Raises FileNotFoundError
    when it is not a folder; a tap file that cannot be read becomes a note."""
    if not folder.is_dir():
        raise FileNotFoundError(errno.ENOENT, "no such tap folder", str(folder))
    by_group: dict[str, list[TapEntry]] = defaultdict(list)
    for path in tap_files(folder):
        try:
            for entry in read_tap(path, limit=MAX_TAP_BYTES):
                by_group[entry.group].append(entry)
        except (OSError, ValueError) as exc:
            evidence.notes.append(f"{path}: not read ({exc})")
    n = 0
    for entries in by_group.values():
        entries.sort(key=lambda e: e.t)
        messages = _marked([_message(e, i) for i, e in enumerate(entries)], entries)
        evidence.groups.append(_ordered(messages))
        n += len(messages)
    records = _fsm_records(folder, evidence.notes)
    evidence.fsm.extend(records)
    evidence.sources.append(
        f"{folder} (tests): {n} communicates in {len(by_group)} buses and fleets, {len(records)} FSM records"
    )


def gather(runs: Iterable[Path], tap: Path | None = None) -> Evidence:
    """The evidence of run folders ``runs`` and tap folder ``tap`` (None: none). Raises
    FileNotFoundError (naming it) for one that is not a folder."""
    evidence = Evidence()
    for run_dir in runs:
        add_run(evidence, run_dir)
    if tap is not None:
        add_tap(evidence, tap)
    return evidence
