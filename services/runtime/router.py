"""The Zenoh router process: ``python -m services.runtime.router [--listen EP]... [--connect EP]...``.

The eclipse-zenoh Python package runs a router by itself in mode "router" (no zenohd needed;
platform-notes.md). Defaults: listen on ``ROCO_LISTEN`` or ``tcp/0.0.0.0:7447``; ``--connect``
meshes it with other routers (a deployment over several hosts).

Access control (docs/security.md): with ``ROCO_SECURITY`` naming a credentials folder
(services/security/), the router requires user/password authentication, mutual TLS on its
``tls/`` endpoints and applies the folder's ``acl.json`` (default deny). Exit code 2 when that
folder is incomplete. With access control on, every message it refuses is counted and named
(services/runtime/refusals.py): read from Zenoh's own log of its ACL decisions, written to
``$ROCO_RUN_DIR/refusals.jsonl``, announced in the router's log (the first
:data:`ANNOUNCED` of them, then one line per thousand) and reported on ``roco/counters/ask``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import FrameType
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
from services.runtime.transport import router_config

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
    thread of its own (Zenoh is not called from its callbacks, platform-notes.md) until
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="roco-router")
    parser.add_argument("--listen", action="append", default=None)
    parser.add_argument("--connect", action="append", default=None)
    args = parser.parse_args(argv)
    listen = args.listen or [os.environ.get("ROCO_LISTEN", "tcp/0.0.0.0:7447")]
    connect = args.connect or [e for e in os.environ.get("ROCO_CONNECT", "").split(",") if e]
    security = os.environ.get("ROCO_SECURITY", "").strip()
    try:
        conf = router_config(listen, connect, security=Path(security) if security else None)
    except (OSError, ValueError) as exc:
        print(f"roco router: ROCO_SECURITY: {exc}", file=sys.stderr)
        return 2
    run_dir = os.environ.get("ROCO_RUN_DIR", "").strip()
    refusals = watch_refusals(Path(run_dir) if run_dir else None) if security else None
    session = zenoh.open(conf)
    done = threading.Event()
    asked = answer_counters(session, refusals, done) if refusals is not None else None

    def on_signal(signum: int, frame: FrameType | None) -> None:
        done.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    acl = f"; access control from {security}" if security else "; no access control"
    print(f"roco router {session.zid()} listening on {', '.join(listen)}{acl}", flush=True)
    done.wait()
    if asked is not None:
        asked.undeclare()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
