"""The Zenoh router process: ``python -m services.runtime.router [--listen EP]... [--connect EP]...``.

The eclipse-zenoh Python package runs a router by itself in mode "router": no zenohd is needed
(none is on PyPI or in Debian). Defaults: listen on ``ROCO_LISTEN`` or ``tcp/0.0.0.0:7447``;
``--connect`` meshes it with other routers (a deployment over several hosts).

Access control (docs/security.md): with ``ROCO_SECURITY`` naming a credentials folder
(services/security/), the router requires user/password authentication, mutual TLS on its
``tls/`` endpoints and applies the folder's ``acl.json`` (default deny). Exit code 2 when that
folder is incomplete. With access control on, every message it refuses is counted and named
(services/runtime/refusal_watch.py): read from Zenoh's own log, written to
``$ROCO_RUN_DIR/refusals.jsonl``, announced in the router's log and reported on
``roco/counters/ask``.

Zenoh's own log goes to standard output at ``RUST_LOG``'s level, INFO when unset
(services/runtime/zenoh_log.py: what the refusal watch turns on beyond it is read, not passed
on). ``ROCO_READY_FILE`` (shared/ready_file.py) is written once the router listens and removed
when it stops: a container's health check reads it, and opens no connection to the router.

A router of a mesh (docs/deploy.md, "Two machines", "Two hosts on one machine") runs with
``--identity router_<host>`` (or ``ROCO_ROUTER_IDENTITY``): it serves and connects with that
identity's certificate, so the routers' link is mutual TLS; ``--lease-ms`` sets how long a
silent link is kept (Zenoh's default 10 s).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from types import FrameType

from services.runtime.refusal_watch import answer_counters, watch_refusals
from services.runtime.refusals import RefusalLog
from services.runtime.zenoh_config import open_session, router_config
from services.runtime.zenoh_log import capture_zenoh_log
from shared.ready_file import clear as clear_ready
from shared.ready_file import mark as mark_ready
from shared.settings import Settings

SIGNAL_POLL_S = 0.5
"""s between the main thread's looks for SIGTERM/SIGINT's handler having run."""


def main(argv: list[str] | None = None) -> int:
    read = Settings.from_env(
        only=("router_identity", "listen", "connect", "security", "run_dir", "ready_file")
    )
    clear_ready(read.ready_file)  # a file a killed router left does not speak for this one
    parser = argparse.ArgumentParser(prog="roco-router")
    parser.add_argument("--listen", action="append", default=None)
    parser.add_argument(
        "--identity",
        default=read.router_identity,
        help="a meshed router's identity in the credentials folder (ROCO_ROUTER_IDENTITY)",
    )
    parser.add_argument("--lease-ms", type=int, default=None, help="Zenoh's transport lease (default 10000)")
    parser.add_argument("--connect", action="append", default=None)
    args = parser.parse_args(argv)
    listen = args.listen or [read.listen]
    connect = args.connect or list(read.connect)
    security = read.security
    try:
        conf = router_config(
            listen,
            connect,
            security=security,
            identity=args.identity if security else None,
            lease_ms=args.lease_ms,
        )
    except (OSError, ValueError) as exc:
        print(f"roco router: {Settings.env_name('security')}: {exc}", file=sys.stderr)
        return 2
    if security:
        refusals: RefusalLog | None = watch_refusals(read.run_dir)
    else:
        refusals = None
        capture_zenoh_log(lambda _line: False)
    try:
        session = open_session(conf)
    except ValueError as exc:  # a ZENOH_RUNTIME Zenoh cannot read
        print(f"roco router: {exc}", file=sys.stderr)
        return 2
    done = threading.Event()
    asked = answer_counters(session, refusals, done) if refusals is not None else None

    def on_signal(signum: int, frame: FrameType | None) -> None:
        done.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    acl = f"; access control from {security}" if security else "; no access control"
    listening = f"roco router {session.zid()} listening on {', '.join(listen)}{acl}"
    print(listening, flush=True)
    if (why := mark_ready(read.ready_file, listening)) is not None:
        print(f"roco router: {why}", file=sys.stderr, flush=True)
    # wait with a timeout: a signal delivered to one of Zenoh's threads does not wake a main
    # thread blocked without one, and its handler would then never run (seen: a router left
    # running after SIGTERM)
    while not done.wait(SIGNAL_POLL_S):
        pass
    clear_ready(read.ready_file)
    if asked is not None:
        asked.undeclare()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
