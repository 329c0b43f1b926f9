"""A run folder holding a traffic record written as the recorder writes it (services/recorder/
record.py: ``traffic.jsonl`` and ``traffic.msgpack``, one publisher per key with its sequence
numbers), from communicates given with their times: a few conversations of a real agent, for
tests that read a record (``roco replay``) without running a fleet."""

from __future__ import annotations

import shutil
import subprocess
import sys
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import msgspec

from services.recorder.presence import PRESENCE_JSONL, PresenceEvent
from services.recorder.record import TRAFFIC_RAW, RawEntry, encode_entry, read_entries, record_of
from services.report.load import Message
from services.runtime import keys
from services.runtime.run_folder import RUN_INFO, TRAFFIC_JSONL, RunInfo, write_run_info
from services.runtime.transport import Arrival
from services.spec.model import channel_between, default_spec
from shared.fipa_codec import Communicate, encode

STARTED = 1_800_000_000.0
"""When the written runs began (POSIX s)."""


def write_recorded_run(
    run_dir: Path,
    traffic: list[tuple[float, Communicate]],
    alive: list[str] | None = None,
    sent: list[float | None] | None = None,
) -> Path:
    """``run_dir`` (made) with ``run.json`` and a traffic record of ``traffic``: (s after
    :data:`STARTED`, communicate) in the order they crossed Zenoh, each on the key of the
    specification's channel between its sender and its first receiver; with ``alive``, a
    presence record in which those processes were alive throughout (and no other), else none
    (every agent alive, services/replay/presence.py). ``sent``: per communicate, when its
    publisher stamped it (s after :data:`STARTED`; None, or no ``sent``: when it crossed)."""
    if alive is not None:
        write_presence(
            run_dir,
            [
                PresenceEvent(name=n, alive=True, t=STARTED, seq=0, incarnation="test", snapshot=True)
                for n in alive
            ],
        )
    run_dir.mkdir(parents=True, exist_ok=True)
    write_run_info(run_dir, RunInfo(started=STARTED))
    spec = default_spec()
    sn: defaultdict[str, int] = defaultdict(int)
    lines, raw = [], []
    stamps = sent if sent is not None else [None] * len(traffic)
    assert len(stamps) == len(traffic)
    for seq, ((t, msg), stamp) in enumerate(zip(traffic, stamps, strict=True)):
        assert msg.sender is not None and msg.receiver
        sender, receiver = msg.sender.name, msg.receiver[0].name
        channel = channel_between(spec, sender, receiver)
        assert channel is not None, (sender, receiver)
        key = keys.fipa_key(channel.name, sender, receiver)
        t_sent = STARTED + (t if stamp is None else stamp)
        arrival = Arrival(STARTED + t, key, encode(msg), f"{sender}-session:{key}", sn[key], t_sent)
        sn[key] += 1
        entry = RawEntry("test", seq, arrival)
        lines.append(msgspec.json.encode(record_of(entry)) + b"\n")
        raw.append(encode_entry(entry))
    (run_dir / TRAFFIC_JSONL).write_bytes(b"".join(lines))
    (run_dir / TRAFFIC_RAW).write_bytes(b"".join(raw))
    return run_dir


RECORD_FILES = (RUN_INFO, TRAFFIC_JSONL, TRAFFIC_RAW, PRESENCE_JSONL)
"""The files of a run folder that hold its traffic record, its presence record and when it
began."""


def write_presence(run_dir: Path, events: list[PresenceEvent]) -> Path:
    """``run_dir`` (made) with a presence record of ``events``, in their order."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / PRESENCE_JSONL).write_bytes(b"".join(msgspec.json.encode(e) + b"\n" for e in events))
    return run_dir


def copy_record(run_dir: Path, dest: Path) -> Path:
    """``dest`` (made) with a copy of ``run_dir``'s traffic record, presence record (if it has
    one) and ``run.json``, to be mutated without touching the run."""
    dest.mkdir(parents=True, exist_ok=True)
    for name in RECORD_FILES:
        if name != PRESENCE_JSONL or (run_dir / name).exists():
            shutil.copyfile(run_dir / name, dest / name)
    return dest


def rewrite_record(run_dir: Path, change: Callable[[list[RawEntry]], list[RawEntry]]) -> Path:
    """Write ``run_dir``'s traffic record again, both files, as ``change`` makes its raw entries
    (given in the order written): a communicate dropped, recorded twice, or by another recorder
    incarnation."""
    entries = [e for e, _, _, _ in read_entries(run_dir) if e is not None]
    kept = change(entries)
    (run_dir / TRAFFIC_JSONL).write_bytes(b"".join(msgspec.json.encode(record_of(e)) + b"\n" for e in kept))
    (run_dir / TRAFFIC_RAW).write_bytes(b"".join(encode_entry(e) for e in kept))
    return run_dir


def answer_before_its_cause(
    messages: list[Message], cause_from: str, asker: str, answerer: str
) -> tuple[list[Message], Message, Message]:
    """``messages`` (as recorded) with an answer put just before what caused its question, as
    publishers linked directly may reach the recorder: the cause, the first communicate from
    ``cause_from`` to ``asker`` (by its sender's timestamp); the question, ``asker``'s first to
    ``answerer`` sent after the cause was; the answer, ``answerer``'s that names the question's
    reply-with (in-reply-to, in the same conversation). All three are found by cause, whatever
    order the record holds them in (the answer may be recorded before the cause already).
    Returns (that order, the cause, the answer)."""

    def sent(m: Message) -> float:
        return m.rec.t_sent if m.rec.t_sent is not None else m.rec.t

    def between(a: str, b: str) -> list[Message]:
        found = [m for m in messages if m.comm is not None and (m.sender, *m.rec.receivers[:1]) == (a, b)]
        return sorted(found, key=sent)

    cause = between(cause_from, asker)[0]
    question = next(m for m in between(asker, answerer) if sent(m) >= sent(cause))
    assert question.comm is not None and question.comm.reply_with is not None, question.rec
    asked = (question.comm.conversation_id, question.comm.reply_with)
    answer = next(
        m
        for m in between(answerer, asker)
        if m.comm is not None and (m.comm.conversation_id, m.comm.in_reply_to) == asked
    )
    order = [m for m in messages if m is not answer]
    order.insert(order.index(cause), answer)
    return order, cause, answer


def replay_lines(run_dir: Path) -> dict[str, str]:
    """``roco replay RUN``'s line per agent, by agent (its exit status checked: 0)."""
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "replay", str(run_dir)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    return {line.partition(":")[0]: line for line in proc.stdout.strip().splitlines()}
