"""The recorder-sync barrier, seen from a tool (``roco down``, ``roco hosts down``, the scenario
runner, ``roco fault``): a token put on ``roco/recorder/sync`` reaches the traffic recorder after
every communicate routed before it; the recorder writes them all, then puts the token back on
``roco/recorder/synced`` (services/recorder/recorder.py). Once it is back, stopping the fleet
loses nothing of its traffic record.

A sync may carry fault events (:class:`SyncRequest`, JSON): the recorder writes them to
``faults.jsonl`` before it answers, once per token, so the answer means "written". A put can be
lost (congestion control DROP; after a router restart, a subscription the router or the
putting session does not know yet), hence the tool sends the same sync again until it is
answered. Payloads: a bare token (any bytes not starting with ``{``; the answer is the payload
itself) or a :class:`SyncRequest` (the answer is its ``token``).
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

import msgspec
import zenoh

from services.runtime import keys
from services.runtime.faults import FaultEvent
from services.runtime.session import open_client
from services.security.context import register

SYNC_TIMEOUT_S = 10.0
"""How long a tool waits for the recorder's answer by default (s)."""
RESEND_S = 0.5
"""How long (s) a tool waits for the answer before it sends the same sync again."""
CONFIRMED = "traffic record complete"
"""What a tool says once the recorder answered."""
NOT_CONFIRMED = "traffic record not confirmed"
"""What it says when the recorder did not answer (the record may lack the last communicates)."""
INJECTOR = "roco"
"""The ``agent`` of every fault event a sync may carry: the operator's process and container
faults (``roco fault``, ``roco chaos``, the scenario runner), whose own event key is
``roco/fault/event/roco`` (services/spec_check/acl.py: the only one the operator may put)."""
MAX_SYNC_BYTES = 64 * 1024
"""The largest sync payload the recorder decodes (bytes)."""
MAX_EVENTS = 64
"""The most fault events one sync carries; :func:`record` sends more as several syncs."""


class SyncRequest(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """A sync that carries fault events: ``token`` (1–64 characters, fresh per request) and
    ``events`` (at most :data:`MAX_EVENTS`, each of agent :data:`INJECTOR`)."""

    token: Annotated[str, msgspec.Meta(min_length=1, max_length=64)]
    events: Annotated[list[FaultEvent], msgspec.Meta(max_length=MAX_EVENTS)]


class BadSync(ValueError):
    """A sync payload the recorder does not answer; the message is one line."""


_request = msgspec.json.Decoder(SyncRequest).decode


def parse(payload: bytes) -> tuple[bytes, list[FaultEvent]]:
    """The answer to put back and the fault events to write for a sync ``payload`` (module
    docstring). Raises :class:`BadSync` for one over :data:`MAX_SYNC_BYTES`, a malformed
    request, or an event of another agent than :data:`INJECTOR`."""
    if len(payload) > MAX_SYNC_BYTES:
        raise BadSync(f"a sync of {len(payload)} bytes (at most {MAX_SYNC_BYTES})")
    if not payload.startswith(b"{"):
        return payload, []
    try:
        req = _request(payload)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise BadSync(f"a malformed sync request: {exc}") from None
    others = sorted({e.agent for e in req.events if e.agent != INJECTOR})
    if others:
        raise BadSync(f"a sync request with events of {', '.join(others)} (only {INJECTOR}'s)")
    return req.token.encode(), req.events


def _await(session: zenoh.Session, payload: bytes, answer: bytes, timeout: float) -> bool:
    """Put ``payload`` on ``roco/recorder/sync``, again every :data:`RESEND_S` s, until
    ``answer`` comes back on ``roco/recorder/synced`` (True) or ``timeout`` s passed (False)."""
    deadline = time.monotonic() + timeout
    synced = threading.Event()
    sub = session.declare_subscriber(
        keys.RECORDER_SYNCED, lambda s: synced.set() if s.payload.to_bytes() == answer else None
    )
    try:
        while True:
            session.put(keys.RECORDER_SYNC, payload)
            left = deadline - time.monotonic()
            if synced.wait(max(0.0, min(RESEND_S, left))):
                return True
            if left <= RESEND_S:
                return False
    finally:
        sub.undeclare()


def sync(session: zenoh.Session, timeout: float = SYNC_TIMEOUT_S) -> bool:
    """Put a fresh token on ``roco/recorder/sync`` (again every :data:`RESEND_S` s) and wait up
    to ``timeout`` s for the recorder to put it back; True once it did (everything routed
    before is written), False when it did not answer in time (no recorder, or a router
    between that does not route)."""
    token = uuid.uuid4().hex.encode()
    return _await(session, token, token, timeout)


def record(session: zenoh.Session, events: Sequence[FaultEvent], timeout: float = SYNC_TIMEOUT_S) -> bool:
    """Have the recorder write ``events`` (each of agent :data:`INJECTOR`) to ``faults.jsonl``:
    they travel inside syncs (:class:`SyncRequest`, at most :data:`MAX_EVENTS` each), each
    sent again until answered; True once every one was answered (the events are written, once
    each), False when one was not within ``timeout`` s in all."""
    deadline = time.monotonic() + timeout
    enc = msgspec.json.Encoder()
    chunks = [list(events[i : i + MAX_EVENTS]) for i in range(0, len(events), MAX_EVENTS)] or [[]]
    for chunk in chunks:
        token = uuid.uuid4().hex
        payload = enc.encode(SyncRequest(token=token, events=chunk))
        if not _await(session, payload, token.encode(), deadline - time.monotonic()):
            return False
    return True


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
