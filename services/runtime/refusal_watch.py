"""The router's watch over what its access control refuses: Zenoh's log captured in the router
process and read by a :class:`~services.runtime.refusals.RefusalLog`, the refusals announced in
the router's log, written to the run folder and reported on ``roco/counters/ask``
(docs/security.md, "Refusals seen"). Used by services/runtime/router.py only.
"""

from __future__ import annotations

import contextlib
import os
import queue
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO

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

ANNOUNCED = 100
"""Refusals the router's log names one by one; after them, one line per thousand."""


def capture_zenoh_log(on_line: Callable[[str], bool]) -> None:
    """Turn on Zenoh's log of ACL decisions (:data:`~services.runtime.refusals.LOG_FILTER`
    added to ``RUST_LOG``, default level ``warn``) and pass every line Zenoh writes to
    ``on_line`` on a thread of its own; a line it does not take (returns False) goes on to this
    process's standard output. Zenoh writes its log to file descriptor 1, which becomes a pipe;
    Python's own ``sys.stdout`` keeps the original output. Call before the first session."""
    read_fd, write_fd = os.pipe()
    saved = os.dup(1)
    os.dup2(write_fd, 1)
    os.close(write_fd)
    sys.stdout.flush()
    sys.stdout = os.fdopen(saved, "w", buffering=1)
    rust_log = os.environ.get("RUST_LOG", "").strip() or "warn"
    os.environ["RUST_LOG"] = f"{rust_log},{LOG_FILTER}"
    zenoh.try_init_log_from_env()

    def pump(out: IO[str]) -> None:
        # must never stop: Zenoh would block on a full pipe, and the router with it
        with os.fdopen(read_fd, "r", errors="replace") as lines:
            for line in lines:
                try:
                    taken = on_line(line)
                except Exception as exc:  # a line the parser chokes on is passed on, noted
                    taken = False
                    out.write(f"roco router: reading Zenoh's log: {exc!r}\n")
                if not taken:
                    out.write(line)
                    out.flush()

    threading.Thread(target=pump, args=(sys.stdout,), name="zenoh-log", daemon=True).start()


def watch_refusals(run_dir: Path | None) -> RefusalLog:
    """A :class:`RefusalLog` fed with Zenoh's log (:func:`capture_zenoh_log`), writing
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

    capture_zenoh_log(on_line)
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
