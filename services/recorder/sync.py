"""The recorder-sync barrier, seen from a tool (``roco down``, ``roco hosts down``, the scenario
runner): a token put on ``roco/recorder/sync`` reaches the traffic recorder after every
communicate routed before it; the recorder writes them all, then puts the token back on
``roco/recorder/synced`` (services/recorder/recorder.py). Once it is back, stopping the fleet
loses nothing of its traffic record.
"""

from __future__ import annotations

import threading
import uuid
from pathlib import Path

import zenoh

from services.runtime import keys
from services.runtime.session import open_client
from services.security.context import register

SYNC_TIMEOUT_S = 10.0
"""How long a tool waits for the recorder's answer by default (s)."""
CONFIRMED = "traffic record complete"
"""What a tool says once the recorder answered."""
NOT_CONFIRMED = "traffic record not confirmed"
"""What it says when the recorder did not answer (the record may lack the last communicates)."""


def sync(session: zenoh.Session, timeout: float = SYNC_TIMEOUT_S) -> bool:
    """Put a fresh token on ``roco/recorder/sync`` and wait up to ``timeout`` s for the recorder
    to put it back; True once it did (everything routed before is written), False when it did
    not answer in time (no recorder, or a router between that does not route)."""
    token = uuid.uuid4().hex.encode()
    synced = threading.Event()
    sub = session.declare_subscriber(
        keys.RECORDER_SYNCED, lambda s: synced.set() if s.payload.to_bytes() == token else None
    )
    try:
        session.put(keys.RECORDER_SYNC, token)
        return synced.wait(timeout)
    finally:
        sub.undeclare()


def sync_fleet(endpoint: str, security: Path | None = None, timeout: float = 5.0) -> bool:
    """:func:`sync` through the router at ``endpoint`` on a session of its own, authenticated
    with the credentials folder ``security`` when given (a fleet's ``RUN/security``); False
    also when no router answers there."""
    if security is not None and security.is_dir():
        register(endpoint, security)
    try:
        session = open_client(endpoint)
    except (zenoh.ZError, ValueError):  # the router is gone, or the credentials are
        return False
    try:
        return sync(session, timeout)
    finally:
        session.close()


def sync_words(synced: bool) -> str:
    """:data:`CONFIRMED` or :data:`NOT_CONFIRMED`."""
    return CONFIRMED if synced else NOT_CONFIRMED
