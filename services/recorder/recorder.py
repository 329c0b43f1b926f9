"""The traffic recorder: sees every communicate crossing Zenoh and appends it to the run
folder (``traffic.jsonl`` metadata, ``traffic.msgpack`` raw payloads).

Run as ``python -m services.recorder.recorder`` with ``ROCO_ROUTER`` and ``ROCO_RUN_DIR``.
It announces liveliness as ``recorder`` once its subscription is declared, so a launcher can
start agents only after the recorder listens. A payload that is not a communicate is recorded
with performative ``malformed``. Fault events (``roco/fault/event/*``, docs/faults.md) go to
``faults.jsonl``.
"""

from __future__ import annotations

import logging
import os
import queue
import signal
import sys
import time
from pathlib import Path
from types import FrameType
from typing import BinaryIO

import msgspec

from services.recorder.record import FAULTS_JSONL, TRAFFIC_JSONL, TRAFFIC_RAW, TrafficRecord
from services.runtime import faults, keys
from services.runtime.main import router_endpoints, setup_logging
from services.runtime.transport import ZenohTransport
from services.viewer.hooks import traffic_hook
from shared.fipa_codec import DecodeError, decode

RECORDER = "recorder"
_fault_event = msgspec.json.Decoder(faults.FaultEvent).decode
_FAULT_EVENTS = faults.EVENT_ALL.removesuffix("*")


def to_record(seq: int, t: float, key: str, payload: bytes) -> TrafficRecord:
    """Metadata of one payload seen on ``key`` at POSIX time ``t``."""
    try:
        channel, sender, receiver = keys.parse_fipa_key(key)
    except ValueError:
        channel, sender, receiver = "?", "?", "?"
    try:
        msg = decode(payload)
    except DecodeError:
        return TrafficRecord(
            seq=seq,
            t=t,
            size=len(payload),
            channel=channel,
            sender=sender,
            receivers=(receiver,),
            performative="malformed",
            key=key,
        )
    return TrafficRecord(
        seq=seq,
        t=t,
        size=len(payload),
        channel=channel,
        sender=msg.sender.name if msg.sender else sender,
        receivers=tuple(r.name for r in msg.receiver) or (receiver,),
        performative=msg.performative.value,
        protocol=msg.protocol,
        conversation_id=msg.conversation_id,
        language=msg.language,
        ontology=msg.ontology,
        key=key,
    )


class TrafficWriter:
    """Appends records and raw payloads to a run folder."""

    def __init__(self, run_dir: Path) -> None:
        run_dir.mkdir(parents=True, exist_ok=True)
        self._jsonl = (run_dir / TRAFFIC_JSONL).open("ab")
        self._raw = (run_dir / TRAFFIC_RAW).open("ab")
        self._enc = msgspec.json.Encoder()
        self._mp = msgspec.msgpack.Encoder()
        self.seq = 0
        self._run_dir = run_dir
        self._faults: BinaryIO | None = None  # opened at the first fault event

    def fault(self, payload: bytes) -> bool:
        """Append one fault event (JSON :class:`~services.runtime.faults.FaultEvent`) to
        ``faults.jsonl``; False (nothing written) when it is not one."""
        try:
            event = _fault_event(payload)
        except (msgspec.DecodeError, msgspec.ValidationError):
            return False
        if self._faults is None:
            self._faults = (self._run_dir / FAULTS_JSONL).open("ab")
        self._faults.write(self._enc.encode(event) + b"\n")
        return True

    def write(self, t: float, key: str, payload: bytes) -> TrafficRecord:
        rec = to_record(self.seq, t, key, payload)
        self._jsonl.write(self._enc.encode(rec) + b"\n")
        self._raw.write(self._mp.encode((self.seq, payload)))
        self.seq += 1
        return rec

    def flush(self) -> None:
        self._jsonl.flush()
        self._raw.flush()
        if self._faults is not None:
            self._faults.flush()

    def close(self) -> None:
        self.flush()
        self._jsonl.close()
        self._raw.close()
        if self._faults is not None:
            self._faults.close()


def main() -> int:
    setup_logging(RECORDER)
    run_dir = Path(os.environ.get("ROCO_RUN_DIR", "."))
    writer = TrafficWriter(run_dir)
    rerun = traffic_hook(RECORDER, run_dir)  # Rerun (services/viewer): None unless ROCO_RERUN=1
    inbox: queue.SimpleQueue[tuple[float, str, bytes] | None] = queue.SimpleQueue()
    transport = ZenohTransport(router_endpoints(), identity=RECORDER)
    transport.subscribe(keys.FIPA_ALL, lambda k, p: inbox.put((time.time(), k, p)))
    # a sync token arrives after the traffic routed before it: answer once that is written
    transport.subscribe(keys.RECORDER_SYNC, lambda k, p: inbox.put((time.time(), k, p)))
    transport.subscribe(faults.EVENT_ALL, lambda k, p: inbox.put((time.time(), k, p)))
    transport.announce(keys.alive_key(RECORDER))

    def on_signal(signum: int, frame: FrameType | None) -> None:
        inbox.put(None)

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    logging.getLogger(RECORDER).info("recording to %s", run_dir)
    while True:
        try:
            item = inbox.get(timeout=0.5)
        except queue.Empty:
            writer.flush()
            continue
        if item is None:
            break
        if item[1] == keys.RECORDER_SYNC:
            writer.flush()
            transport.publish(keys.RECORDER_SYNCED, item[2])
            continue
        if item[1].startswith(_FAULT_EVENTS):
            if not writer.fault(item[2]):
                logging.getLogger(RECORDER).warning("ignored a malformed fault event on %s", item[1])
            continue
        record = writer.write(*item)
        if rerun is not None:  # Rerun
            rerun.communicate(record, item[2])
    # drain what is left
    while True:
        try:
            item = inbox.get_nowait()
        except queue.Empty:
            break
        if item is not None and item[1].startswith(_FAULT_EVENTS):
            writer.fault(item[2])
        elif item is not None and item[1] != keys.RECORDER_SYNC:
            record = writer.write(*item)
            if rerun is not None:  # Rerun
                rerun.communicate(record, item[2])
    writer.close()
    transport.close()
    if rerun is not None:  # Rerun: close this part, merge all parts into <run>/recording.rrd
        rerun.finish()
    return 0


if __name__ == "__main__":
    sys.exit(main())
