"""The traffic recorder: sees every communicate crossing Zenoh and appends it to the run
folder (``traffic.jsonl`` metadata, ``traffic.msgpack`` raw payloads).

Run as ``python -m services.recorder.recorder`` with ``ROCO_ROUTER`` and ``ROCO_RUN_DIR``.
It announces liveliness as ``recorder`` once its subscription is declared, so a launcher can
start agents only after the recorder listens, and then writes ``ROCO_READY_FILE`` (a
container's health check: shared/ready_file.py). A payload that is not a communicate is recorded
with performative ``malformed``. Fault events (``roco/fault/event/*``, docs/faults.md, and
those a sync carries: services/recorder/sync.py) go to ``faults.jsonl``. Each communicate
written is also given to the live requirements monitor (:data:`MONITOR`, loaded by name:
services/spec_live/sink.py), which appends the requirement properties it finds violated to
``flags.jsonl`` as they happen (services/recorder/flags.py); the recorder answers queries of
``roco/recorder/flags`` with them (``roco status``).
"""

from __future__ import annotations

import importlib
import logging
import queue
import secrets
import signal
import sys
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import BinaryIO

import msgspec

from services.recorder import sync
from services.recorder.flags import flags_reply
from services.recorder.presence import PresenceEvent, PresenceWriter
from services.recorder.record import (
    FAULTS_JSONL,
    TRAFFIC_JSONL,
    TRAFFIC_RAW,
    RawEntry,
    RecordKey,
    TrafficRecord,
    encode_entry,
    read_entries,
    record_of,
)
from services.runtime import faults, keys
from services.runtime.hooks import TrafficSink, load_hooks
from services.runtime.main import ready_file, router_endpoints, say_ready, setup_logging
from services.runtime.session import alive_agents
from services.runtime.transport import Arrival, ZenohTransport
from shared.ready_file import clear as clear_ready
from shared.settings import Settings

RECORDER = "recorder"
MONITOR = "services.spec_live.sink:open_sink"
"""The live requirements monitor's sink factory (``module:function``, called with the
recorder's name and run folder; it returns a ``TrafficSink`` or None)."""
_fault_event = msgspec.json.Decoder(faults.FaultEvent).decode
_FAULT_EVENTS = faults.EVENT_ALL.removesuffix("*")
_ALIVE = keys.ALIVE_ALL.removesuffix("*")
SNAPSHOT_S = 5.0
"""How long (s) the recorder waits at most for the tokens alive when it starts (a liveliness
query, answered at once by a reachable router)."""
_APPEARED, _GONE, _ALIVE_AT_START = b"+", b"-", b"="
"""What a liveliness token did, as :meth:`_Loop.alive` and :meth:`_Loop.snapshot` enqueue it."""
BATCH = 256
"""Communicates written with one write per file at most (what arrived together)."""
SYNCS_KEPT = 1024
"""How many tokens of syncs that carried fault events the recorder keeps, to write the events
of a sync sent again only once."""
log = logging.getLogger(RECORDER)


@dataclass
class Resume:
    """Where a recorder starting on an existing run folder goes on: ``next_seq`` (one past the
    highest seq written), ``last_sn`` (the highest sequence number recorded per publisher, so
    that what its cache sends again is not written twice) and ``notes`` on what was repaired."""

    next_seq: int = 0
    last_sn: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def repair(run_dir: Path, incarnation: str) -> Resume:
    """Make ``run_dir``'s traffic record whole again before a new recorder ``incarnation``
    appends to it: a raw entry whose record is missing (the previous recorder was killed
    between the two writes) gets its record (:func:`~services.recorder.record.record_of`); a
    truncated or corrupt tail of the raw stream is moved aside to
    ``traffic.msgpack.<incarnation>.tail`` (kept, not read); a record line cut short gets its
    end of line. Returns where to go on. Raises OSError when the files cannot be read or
    written."""
    resume = Resume()
    entries = _raw_entries(run_dir, incarnation, resume)
    rec_path = run_dir / TRAFFIC_JSONL
    lines = rec_path.read_bytes() if rec_path.exists() else b""
    written = _written(lines, resume)
    missing = [e for e in entries if e.ref not in written]
    fix = b"" if not lines or lines.endswith(b"\n") else b"\n"
    if missing or fix:
        with rec_path.open("ab") as f:
            f.write(fix + b"".join(_json(record_of(e)) + b"\n" for e in missing))
    if missing:
        resume.notes.append(f"{len(missing)} record(s) written again from their raw entries")
    _last_sns(entries, resume)
    return resume


def _raw_entries(run_dir: Path, incarnation: str, resume: Resume) -> list[RawEntry]:
    """The whole entries of ``run_dir``'s raw stream (``resume.next_seq`` past them); a
    truncated or corrupt tail is moved aside to ``traffic.msgpack.<incarnation>.tail``, noted."""
    raw_path = run_dir / TRAFFIC_RAW
    entries: list[RawEntry] = []
    good_end = 0
    try:
        for entry, key, _, end in read_entries(run_dir):
            good_end = end
            resume.next_seq = max(resume.next_seq, key.seq + 1)
            if entry is not None:
                entries.append(entry)
    except ValueError as exc:
        data = raw_path.read_bytes()
        tail = raw_path.with_name(f"{TRAFFIC_RAW}.{incarnation}.tail")
        tail.write_bytes(data[good_end:])
        with raw_path.open("r+b") as f:
            f.truncate(good_end)
        resume.notes.append(f"{exc}: {len(data) - good_end} byte(s) moved to {tail.name}")
    return entries


def _written(lines: bytes, resume: Resume) -> set[RecordKey]:
    """The records the record ``lines`` hold (``resume.next_seq`` past them); unreadable lines
    are skipped."""
    written: set[RecordKey] = set()
    for line in lines.splitlines():
        try:
            rec = _record(line)
        except msgspec.DecodeError:
            continue
        written.add(rec.ref)
        resume.next_seq = max(resume.next_seq, rec.seq + 1)
    return written


def _last_sns(entries: list[RawEntry], resume: Resume) -> None:
    """The highest sequence number of ``entries`` per publisher, into ``resume.last_sn``."""
    for e in entries:
        source, sn = e.arrival.source, e.arrival.sn
        if source is not None and sn is not None:
            resume.last_sn[source] = max(resume.last_sn.get(source, -1), sn)


_record = msgspec.json.Decoder(TrafficRecord).decode
_json = msgspec.json.Encoder().encode


class TrafficWriter:
    """Appends communicates to a run folder's traffic record under one recorder incarnation:
    each payload to the raw stream, then its record, each file written unbuffered with one
    write per batch, so that a killed recorder leaves at most payloads without records, which
    :func:`repair` (run when the writer opens) completes."""

    def __init__(self, run_dir: Path, incarnation: str | None = None) -> None:
        """Open (and first :func:`repair`) the traffic record of ``run_dir`` for appending as
        ``incarnation`` (default: a new random id). Raises OSError when it cannot."""
        run_dir.mkdir(parents=True, exist_ok=True)
        self.incarnation = secrets.token_hex(6) if incarnation is None else incarnation
        resume = repair(run_dir, self.incarnation)
        for note in resume.notes:
            log.warning("traffic record repaired: %s", note)
        self.seq = resume.next_seq
        self._last_sn = resume.last_sn
        self._batch_sn: dict[str, int] = {}
        """Per publisher, the sn whose part 0 was admitted last (-1: refused)."""
        self._raw = (run_dir / TRAFFIC_RAW).open("ab", buffering=0)
        self._jsonl = (run_dir / TRAFFIC_JSONL).open("ab", buffering=0)
        self._run_dir = run_dir
        self._faults: BinaryIO | None = None  # opened at the first fault event
        self.duplicates = 0

    def fault(self, payload: bytes) -> bool:
        """Append one fault event (JSON :class:`~services.runtime.faults.FaultEvent`) to
        ``faults.jsonl``; False (nothing written) when it is not one."""
        try:
            event = _fault_event(payload)
        except (msgspec.DecodeError, msgspec.ValidationError):
            return False
        self.fault_event(event)
        return True

    def fault_event(self, event: faults.FaultEvent) -> None:
        """Append ``event`` to ``faults.jsonl`` (buffered: written at :meth:`flush`)."""
        if self._faults is None:
            self._faults = (self._run_dir / FAULTS_JSONL).open("ab")
        self._faults.write(_json(event) + b"\n")

    def admit(self, source: str | None, sn: int | None, part: int = 0) -> bool:
        """Whether a communicate from publisher ``source`` with sequence number ``sn`` is new
        (a publisher's cache sends again what it sent before; the advanced subscriber delivers
        each publisher's communicates in order). ``part`` > 0: a further communicate of the
        batch whose first one (part 0) carried ``sn``; new when that one was. Counts the ones
        refused in ``duplicates``."""
        if source is None or sn is None:
            return True
        if part > 0:
            new = self._batch_sn.get(source) == sn
        else:
            new = sn > self._last_sn.get(source, -1)
            self._batch_sn[source] = sn if new else -1
        if not new:
            self.duplicates += 1
            return False
        self._last_sn[source] = sn
        return True

    def write_many(self, arrivals: list[Arrival]) -> list[TrafficRecord]:
        """Write ``arrivals`` (payloads first, then records); returns their records."""
        entries = [RawEntry(self.incarnation, self.seq + i, a) for i, a in enumerate(arrivals)]
        self.seq += len(entries)
        records = [record_of(e) for e in entries]
        _write_all(self._raw, b"".join(encode_entry(e) for e in entries))
        _write_all(self._jsonl, b"".join(_json(r) + b"\n" for r in records))
        return records

    def write(self, t: float, key: str, payload: bytes) -> TrafficRecord:
        """Write one communicate that arrived at POSIX time ``t`` on ``key`` with no source."""
        return self.write_many([Arrival(t, key, payload)])[0]

    def flush(self) -> None:
        if self._faults is not None:
            self._faults.flush()

    def close(self) -> None:
        self.flush()
        self._jsonl.close()
        self._raw.close()
        if self._faults is not None:
            self._faults.close()


def _write_all(f: BinaryIO, data: bytes) -> None:
    """Write all of ``data`` to the unbuffered ``f`` (a raw write may write only part of it)."""
    view = memoryview(data)
    while view:
        n = f.write(view)
        if not n:
            raise OSError(f"no progress writing {f.name}")
        view = view[n:]


class _Loop:
    """The recorder's thread: writes what the Zenoh callbacks put in ``inbox``."""

    def __init__(
        self,
        writer: TrafficWriter,
        transport: ZenohTransport,
        sinks: list[TrafficSink] | None = None,
        presence: PresenceWriter | None = None,
    ) -> None:
        self.writer, self.transport, self.sinks, self.presence = writer, transport, sinks or [], presence
        self.inbox: queue.SimpleQueue[Arrival | None] = queue.SimpleQueue()
        self.listening_since = time.time()
        self._synced: OrderedDict[bytes, None] = OrderedDict()
        """The tokens of the last :data:`SYNCS_KEPT` syncs whose events were written."""

    def put(self, key: str, payload: bytes) -> None:
        """A callback for Zenoh's threads: enqueue a non-FIPA sample (sync token, fault event)."""
        self.inbox.put(Arrival(time.time(), key, payload))

    def alive(self, key: str, alive: bool) -> None:
        """A callback for Zenoh's threads: a liveliness token appeared or disappeared."""
        self.inbox.put(Arrival(time.time(), key, _APPEARED if alive else _GONE))

    def snapshot(self, names: set[str]) -> None:
        """The tokens alive when this incarnation began to watch (services/recorder/presence.py)."""
        t = time.time()
        for name in sorted(names):
            self.inbox.put(Arrival(t, keys.alive_key(name), _ALIVE_AT_START))

    def run(self) -> None:
        """Write batches of what arrived until ``None`` is enqueued, then what is left."""
        stop = False
        while not stop:
            try:
                first = self.inbox.get(timeout=0.5)
            except queue.Empty:
                self.writer.flush()
                continue
            batch = [first]
            while len(batch) < BATCH:
                try:
                    batch.append(self.inbox.get_nowait())
                except queue.Empty:
                    break
            stop = self._handle(batch)
        rest: list[Arrival | None] = []
        while True:
            try:
                rest.append(self.inbox.get_nowait())
            except queue.Empty:
                break
        self._handle(rest)

    def _handle(self, batch: list[Arrival | None]) -> bool:
        """Write ``batch`` in order; True when it held the stop mark."""
        pending: list[Arrival] = []
        stop = False
        for item in batch:
            if item is None:
                stop = True
            elif item.key == keys.RECORDER_SYNC:
                self._write(pending)  # a sync token arrives after the traffic routed before it
                self._sync(item.payload)
            elif item.key.startswith(_FAULT_EVENTS):
                if not self.writer.fault(item.payload):
                    log.warning("ignored a malformed fault event on %s", item.key)
            elif item.key.startswith(_ALIVE):
                self._write(pending)  # its seq counts what came before it
                self._presence(item)
            elif self.writer.admit(item.source, item.sn, item.part):
                pending.append(self._stamp(item))
        self._write(pending)
        return stop

    def _sync(self, payload: bytes) -> None:
        """Answer a sync (services/recorder/sync.py): write the fault events it carries unless
        its token's were written already (a sync sent again), flush, put the answer back. A bad
        one is logged and not answered."""
        try:
            answer, events = sync.parse(payload)
        except sync.BadSync as exc:
            log.warning("ignored %s", exc)
            return
        if events and answer not in self._synced:
            for event in events:
                self.writer.fault_event(event)
            self._synced[answer] = None
            if len(self._synced) > SYNCS_KEPT:
                self._synced.popitem(last=False)
        self.writer.flush()
        self.transport.publish(keys.RECORDER_SYNCED, answer)

    def _presence(self, a: Arrival) -> None:
        name = keys.alive_agent(a.key)
        if name is None or self.presence is None:
            return
        event = PresenceEvent(
            name=name,
            alive=a.payload != _GONE,
            t=a.t,
            seq=self.writer.seq,
            incarnation=self.writer.incarnation,
            snapshot=a.payload == _ALIVE_AT_START,
        )
        try:
            self.presence.write([event])
        except OSError:
            log.exception("cannot write the presence record; recording traffic without it")
            self.presence = None

    def _stamp(self, a: Arrival) -> Arrival:
        """A communicate sent before this incarnation listened came from its publisher's cache:
        recorded as late, at the time it was sent."""
        if a.t_sent is not None and a.t_sent < self.listening_since:
            return a._replace(t=a.t_sent, late=True)
        return a

    def _write(self, pending: list[Arrival]) -> None:
        if not pending:
            return
        records = self.writer.write_many(pending)
        for sink in self.sinks:  # a viewer, the live requirements monitor
            for rec, a in zip(records, pending, strict=True):
                sink.communicate(rec, a.payload)
        pending.clear()


def _requirements_monitor(run_dir: Path) -> TrafficSink | None:
    """The live requirements monitor's sink (:data:`MONITOR`) for ``run_dir``; None when it
    cannot be loaded or started (logged: a monitor is never a reason to lose traffic) or has
    nothing to watch."""
    module, _, attribute = MONITOR.partition(":")
    try:
        sink: TrafficSink | None = getattr(importlib.import_module(module), attribute)(RECORDER, run_dir)
    except Exception:
        log.exception("the live requirements monitor cannot be started; recording without it")
        return None
    return sink


def main() -> int:
    try:
        setup_logging(RECORDER)
    except ValueError as exc:  # a bad ROCO_LOG_LEVEL
        print(f"roco: recorder: {exc}", file=sys.stderr)
        return 2
    ready = ready_file()
    run_dir = Settings.from_env(only=("run_dir",)).run_dir or Path(".")
    writer = TrafficWriter(run_dir)
    hooks = load_hooks()  # a viewer's, named by string (services/runtime/hooks.py); None: none
    rerun = hooks.traffic(RECORDER, run_dir) if hooks is not None else None
    try:
        transport = ZenohTransport(router_endpoints(), identity=RECORDER)
    except ValueError as exc:  # no credentials for the recorder, a malformed ROCO_RECEIVE_POLL_US
        print(f"roco: recorder: {exc}", file=sys.stderr)
        return 2
    monitor = _requirements_monitor(run_dir)
    presence = PresenceWriter(run_dir)
    loop = _Loop(writer, transport, [s for s in (rerun, monitor) if s is not None], presence)
    # every communicate, and what publishers' caches still hold of those sent before this start;
    # enqueued on the network thread that read them, so that a sync token comes after what was
    # routed before it (on threads of their own a sync overtook communicates: 2 rounds in 200)
    transport.subscribe_recovering(keys.FIPA_ALL, loop.inbox.put, direct=True)
    transport.subscribe(keys.RECORDER_SYNC, loop.put, direct=True)
    transport.subscribe(faults.EVENT_ALL, loop.put, direct=True)
    transport.serve(keys.RECORDER_FLAGS, lambda: flags_reply(run_dir))
    # the processes' liveliness tokens: what is alive now, then each change (presence.jsonl)
    transport.watch(keys.ALIVE_ALL, loop.alive, history=False, direct=True)
    loop.snapshot(alive_agents(transport.session, timeout=SNAPSHOT_S))
    transport.announce(keys.alive_key(RECORDER))

    def on_signal(signum: int, frame: FrameType | None) -> None:
        loop.inbox.put(None)

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    log.info("recording to %s as incarnation %s", run_dir, writer.incarnation)
    say_ready(ready, f"{RECORDER} ready: recording to {run_dir} as incarnation {writer.incarnation}")
    loop.run()
    clear_ready(ready)
    if writer.duplicates:
        log.info(
            "%d communicate(s) sent again by publishers' caches were recorded already", writer.duplicates
        )
    writer.close()
    presence.close()
    transport.close()
    log.info("recording stopped: the record holds %d communicate(s)", writer.seq)
    if monitor is not None:  # what it held back, evaluated
        monitor.finish()
    if rerun is not None:  # a viewer: Rerun closes this part and merges all into <run>/recording.rrd
        rerun.finish()
    return 0


if __name__ == "__main__":
    sys.exit(main())
