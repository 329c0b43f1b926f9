"""Transport: how buffers reach other agents. Zenoh in client mode against a router
(design.md), explicit endpoints, no multicast scouting.

Subscriber callbacks run on Zenoh's threads and only enqueue (calling Zenoh from inside a
callback has deadlocked: platform-notes.md); all publishing happens on the agent's thread.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import zenoh

from services.runtime.limits import low_pass_filter
from services.security.context import identity_name, security_for

Callback = Callable[[str, bytes], None]
AliveCallback = Callable[[str, bool], None]


class Transport(Protocol):
    """What the runtime needs of a transport."""

    def publish(self, key: str, payload: bytes) -> None: ...
    def subscribe(self, key_expr: str, callback: Callback) -> None: ...
    def announce(self, key: str) -> None: ...
    def watch(self, key_expr: str, callback: AliveCallback) -> None: ...
    def close(self) -> None: ...


CONNECT_RETRY = {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2}
"""How often a session tries its endpoints again while it has no connection: 0.1 s, then
doubling up to 1 s (Zenoh's default: 1 s doubling up to 4 s). A client whose router is lost
(e.g. killed and started again on the same endpoint) reconnects by itself on this schedule and
Zenoh declares its subscribers and liveliness tokens again: the session is back within ~1 s of
the router listening again (docs/recovery.md, "Router restart")."""


def client_config(
    endpoints: list[str],
    *,
    wait_for_router: bool = True,
    identity: str | None = None,
    security: Path | None = None,
) -> zenoh.Config:
    """A Zenoh client configuration connecting to ``endpoints`` (e.g. ``tcp/127.0.0.1:7447``
    or ``tls/127.0.0.1:7447``) with multicast scouting off. ``wait_for_router`` retries forever
    instead of failing ``zenoh.open`` after ~0.1 s when no router answers (platform-notes.md).
    Either way a session that loses its router reconnects on the :data:`CONNECT_RETRY`
    schedule, forever.

    Credentials (docs/security.md): from the folder ``security``, else the one found for
    ``endpoints`` (services/security/context.py); with one, the session authenticates as
    ``identity`` (else ``ROCO_IDENTITY``, else ``operator``) with its user name and password
    and, on ``tls/`` endpoints, its certificate (mutual TLS, checked against the folder's CA).
    Raises services.security.certs.CredentialError (a ValueError) when the folder has no
    credentials for that identity."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps(endpoints))
    conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if wait_for_router:
        conf.insert_json5("connect/timeout_ms", "-1")
    folder = security if security is not None else security_for(endpoints)
    if folder is not None:
        _client_auth(conf, folder, identity_name(identity))
    return conf


def _client_auth(conf: zenoh.Config, folder: Path, identity: str) -> None:
    from services.security.certs import identity as load_identity

    ident = load_identity(folder, identity)
    conf.insert_json5("transport/auth/usrpwd/user", json.dumps(ident.name))
    conf.insert_json5("transport/auth/usrpwd/password", json.dumps(ident.password))
    tls = {
        "root_ca_certificate": str(ident.ca),
        "connect_private_key": str(ident.key),
        "connect_certificate": str(ident.cert),
        "enable_mtls": True,
    }
    conf.insert_json5("transport/link/tls", json.dumps(tls))


def router_config(
    listen: list[str], connect: list[str] | None = None, *, security: Path | None = None
) -> zenoh.Config:
    """A Zenoh router configuration listening on ``listen``, optionally meshed with other
    routers at ``connect`` (reconnected on the :data:`CONNECT_RETRY` schedule when one of them
    restarts); multicast scouting off.

    With a credentials folder ``security`` (services/security/certs.py) the router requires
    user/password authentication (its ``passwords.txt``), serves ``tls/`` endpoints with
    ``router.pem`` and requires a client certificate from the folder's CA (mutual TLS), and
    applies the access control of ``acl.json`` (services/spec/acl.py; default deny). Every
    router drops a message above the codec's size limit (``services.runtime.limits``). Raises
    OSError or ValueError when a file is missing or malformed."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"')
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
        conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    # the codec's limit, enforced again where every message passes (issue 8)
    conf.insert_json5("low_pass_filter", json.dumps(low_pass_filter()))
    if security is not None:
        from services.security.certs import ACL_FILE, CA_CERT, PASSWORDS, ROUTER

        acl = json.loads((security / ACL_FILE).read_text())
        for name in (PASSWORDS, CA_CERT, f"{ROUTER}.key", f"{ROUTER}.pem"):
            if not (security / name).is_file():
                raise OSError(f"{security / name}: missing")
        conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(security / PASSWORDS)))
        tls = {
            "root_ca_certificate": str(security / CA_CERT),
            "listen_private_key": str(security / f"{ROUTER}.key"),
            "listen_certificate": str(security / f"{ROUTER}.pem"),
            "enable_mtls": True,
        }
        conf.insert_json5("transport/link/tls", json.dumps(tls))
        conf.insert_json5("access_control", json.dumps(acl))
    return conf


MAX_KEYS = 256
"""Key expressions a :class:`ZenohTransport` keeps parsed (an agent puts on a few keys: one per
peer and channel); further keys are parsed at each put."""


class ZenohTransport:
    """A :class:`Transport` over one Zenoh session."""

    def __init__(
        self, endpoints: list[str], *, wait_for_router: bool = True, identity: str | None = None
    ) -> None:
        """Open a client session to ``endpoints`` as ``identity`` (:func:`client_config`)."""
        self.session = zenoh.open(
            client_config(endpoints, wait_for_router=wait_for_router, identity=identity)
        )
        self._subs: list[zenoh.Subscriber] = []
        self._tokens: list[tuple[str, zenoh.LivelinessToken]] = []
        self._lock = threading.Lock()
        self._keys: dict[str, zenoh.KeyExpr] = {}

    def publish(self, key: str, payload: bytes) -> None:
        """Put ``payload`` on ``key`` (its key expression parsed once and kept: a put costs
        ≈ 1.2 µs instead of ≈ 3.5 µs with a string key) with congestion control BLOCK: when
        the link's queue is full the agent waits instead of the communicate being dropped
        (Zenoh's default for ``put`` drops after 1 ms: a burst of 5,000 communicates lost
        2,000 of them; docs/benchmarks.md). No declared publisher: with access control a
        publisher may never learn of a subscriber the ACL hides from it, and drop everything.
        Called on the agent's thread only."""
        expr = self._keys.get(key)
        if expr is None:
            expr = zenoh.KeyExpr(key)
            if len(self._keys) < MAX_KEYS:
                self._keys[key] = expr
        self.session.put(expr, payload, congestion_control=zenoh.CongestionControl.BLOCK)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.payload.to_bytes())

        with self._lock:
            self._subs.append(self.session.declare_subscriber(key_expr, on_sample))

    def announce(self, key: str) -> None:
        """Declare a liveliness token on ``key`` for the life of this transport."""
        with self._lock:
            self._tokens.append((key, self.session.liveliness().declare_token(key)))

    def withdraw(self, key: str) -> None:
        """Undeclare the liveliness tokens on ``key`` (``announce`` declares it again); used by
        the fault layer to make a partitioned agent look gone."""
        with self._lock:
            gone = [tok for k, tok in self._tokens if k == key]
            self._tokens = [(k, tok) for k, tok in self._tokens if k != key]
        for tok in gone:
            tok.undeclare()

    def watch(self, key_expr: str, callback: AliveCallback) -> None:
        """Call ``callback(key, alive)`` whenever a liveliness token matching ``key_expr``
        appears (True; tokens alive at the time of the call included) or disappears (False:
        undeclared, or its owner's session ended or was lost). Runs on Zenoh's threads."""

        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        with self._lock:
            self._subs.append(self.session.liveliness().declare_subscriber(key_expr, on_sample, history=True))

    def close(self) -> None:
        for _, tok in self._tokens:
            tok.undeclare()
        for sub in self._subs:
            sub.undeclare()
        self.session.close()
