"""The router's watch over what its access control refuses: Zenoh's log captured in the router
process (services/runtime/zenoh_log.py) and read by a
:class:`~services.runtime.refusals.RefusalLog`, the refusals announced in the router's log,
written to the run folder and reported on ``roco/counters/ask`` (docs/security.md, "Refusals
seen"). Used by services/runtime/router.py only.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from pathlib import Path

import msgspec
import zenoh

from services.runtime import keys
from services.runtime.refusals import (
    ACL_TARGET,
    LOG_FILTER,
    REFUSALS_JSONL,
    REPORT_PREFIX,
    UNKNOWN,
    RefusalLog,
)
from services.runtime.zenoh_log import capture_zenoh_log

ANNOUNCED = 100
"""Refusals the router's log names one by one; after them, one line per thousand."""


def watch_refusals(run_dir: Path | None) -> RefusalLog:
    """A :class:`RefusalLog` fed with Zenoh's log (services/runtime/zenoh_log.py, with
    :data:`~services.runtime.refusals.LOG_FILTER` turned on), writing
    ``run_dir/refusals.jsonl`` when a run folder is given, naming refusals in this log."""
    out = (run_dir / REFUSALS_JSONL).open("a") if run_dir is not None and run_dir.is_dir() else None
    log = RefusalLog(out)

    def on_line(line: str) -> bool:
        refusal = log.feed(line)
        if refusal is None:
            # the ACL's decisions and the accepted connections: not for the log
            return (ACL_TARGET in line and "TRACE" in line) or ("DEBUG" in line and "Accepted T" in line)
        n = log.counters["refused"]
        if n <= ANNOUNCED or n % 1000 == 0:
            what = f"{refusal.message} ({refusal.flow}) {refusal.key}".rstrip()
            who = refusal.identity
            if who == UNKNOWN:
                who = f"unnamed session {refusal.session}" if refusal.session else "a client"
            if refusal.peer:
                who += f" from {refusal.peer}"
            print(f"roco router: refused #{n}: {who} {what}", flush=True)
        return True

    capture_zenoh_log(on_line, LOG_FILTER)
    return log


def answer_counters(session: zenoh.Session, log: RefusalLog, done: threading.Event) -> zenoh.Subscriber:
    """Answer every put on ``roco/counters/ask`` with this router's
    :class:`~services.runtime.refusals.RefusalReport` on ``roco/refusals/report/<zid>``, from a
    thread of its own (Zenoh is not called from its callbacks: that has deadlocked) until
    ``done``. The router's own session is not subject to its access control."""
    zid = str(session.zid())
    key = f"{REPORT_PREFIX}/{zid}"
    asks: queue.SimpleQueue[None] = queue.SimpleQueue()

    def answer() -> None:
        while not done.is_set():
            try:
                asks.get(timeout=0.5)
            except queue.Empty:
                continue
            with contextlib.suppress(zenoh.ZError):
                session.put(key, msgspec.json.encode(log.report(zid, time.time())))

    threading.Thread(target=answer, name="refusals", daemon=True).start()
    return session.declare_subscriber(keys.COUNTERS_ASK, lambda _sample: asks.put(None))
