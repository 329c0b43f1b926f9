"""Zenoh's configuration for roco's processes: a client's (an agent's session against its
router), a member's (a session that links to its peers directly: ``ROCO_LINKS=peer``) and a
router's, with their endpoints, reconnection schedule, runtime pools, authentication (mutual
TLS, user and password) and access control (docs/security.md); and opening a session with one.
services/runtime/transport.py moves communicates over the sessions these configure."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Literal

import zenoh

from services.runtime.acl_kinds import ACL_MESSAGES
from services.runtime.limits import low_pass_filter
from services.security.context import identity_name, security_for
from shared.settings import Settings

CONNECT_RETRY = {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2}
"""How often a session tries its endpoints again while it has no connection: 0.1 s, then
doubling up to 1 s (Zenoh's default: 1 s doubling up to 4 s). A client whose router is lost
(e.g. killed and started again on the same endpoint) reconnects by itself on this schedule and
Zenoh declares its subscribers and liveliness tokens again: the session is back within ~1 s of
the router listening again (docs/recovery.md, "Router restart")."""


RUNTIME_POOLS = (
    "(rx: (handover: app), net: (handover: app), acc: (handover: app),"
    " app: (worker_threads: 1), tx: (worker_threads: 1))"
)
"""Zenoh's runtime pools in a roco client process (``ZENOH_RUNTIME``, RON, read by zenoh-runtime
at a process's first session): the receiving (``rx``), network (``net``) and accepting (``acc``)
pools handed over to one application thread, and one transmitting thread, instead of Zenoh's
default of six pools and seven threads. A communicate then wakes one Zenoh thread where it
arrives instead of three: with 100 agent processes doing round trips at once (with
:func:`_no_shared_memory` and the inline budget in CPU time), 20 context switches a round trip
instead of 27 and ≈ 20 % more round trips a second (docs/benchmarks.md, "Fewer wake-ups per
communicate"). Clients only: a router whose links all share one receiving thread
stops reading every link while it waits for room in one full link, and two sessions streaming
to each other through it deadlocked (tests/runtime/test_inline_receive.py); routers keep
Zenoh's own pools (:func:`use_router_pools`)."""

ENV_RUNTIME = "ZENOH_RUNTIME"


def use_runtime_pools() -> None:
    """Give this client process roco's Zenoh runtime pools (:data:`RUNTIME_POOLS`) unless
    ``ZENOH_RUNTIME`` is set; effective only before the process's first Zenoh session (the
    pools are built then), which every roco client opens through :func:`client_config`.
    Child processes inherit the setting (a router drops it: :func:`use_router_pools`)."""
    os.environ.setdefault(ENV_RUNTIME, RUNTIME_POOLS)


def use_router_pools() -> None:
    """Give this router process Zenoh's own runtime pools: drop a ``ZENOH_RUNTIME`` of
    :data:`RUNTIME_POOLS` inherited from a roco client process that started it (a value the
    user set otherwise is kept). Effective only before the process's first Zenoh session."""
    if os.environ.get(ENV_RUNTIME) == RUNTIME_POOLS:
        del os.environ[ENV_RUNTIME]


def open_session(conf: zenoh.Config) -> zenoh.Session:
    """``zenoh.open(conf)``, with a ``ZENOH_RUNTIME`` that Zenoh cannot read (zenoh-runtime
    panics on a malformed RON value at the process's first session) raised as ValueError naming
    the variable, so that a process started with one says so in one line. Raises what
    ``zenoh.open`` raises otherwise (zenoh.ZError: no router answers, credentials refused)."""
    try:
        return zenoh.open(conf)
    except BaseException as exc:  # pyo3's PanicException is a BaseException
        text = str(exc)
        if type(exc).__name__ == "PanicException" and "RuntimeParam" in text and ENV_RUNTIME in os.environ:
            why = text.splitlines()[0][:200] if text else type(exc).__name__
            raise ValueError(
                f"{ENV_RUNTIME}={os.environ[ENV_RUNTIME]!r}: Zenoh cannot read it ({why})"
            ) from None
        raise


def _no_shared_memory(conf: zenoh.Config) -> None:
    """Turn off Zenoh's shared-memory transport (on by default since eclipse-zenoh 1.x, for
    puts of 3,072 B and more to sessions on the same host). Its watchdog wakes a thread of
    every process 20 times a second (zenoh-shm ``WatchdogConfirmator``, 50 ms) whether or not
    anything is ever put through it: 2,000 wake-ups a second for 100 agents, ≈ 8 % of a core
    while they are idle. roco's only large puts are ag_ex's state and world snapshots (kB, 20 Hz),
    which loopback TCP carries as well; no pool is mapped and no ``/dev/shm/*.zenoh`` segment
    is left behind by a killed process."""
    conf.insert_json5("transport/shared_memory/enabled", "false")


def client_config(
    endpoints: list[str],
    *,
    wait_for_router: bool = True,
    identity: str | None = None,
    security: Path | None = None,
) -> zenoh.Config:
    """A Zenoh client configuration connecting to ``endpoints`` (e.g. ``tcp/127.0.0.1:7447``
    or ``tls/127.0.0.1:7447``) with multicast scouting off. ``wait_for_router`` retries forever
    instead of failing ``zenoh.open`` after ~0.1 s when no router answers (zenoh's
    ``connect/timeout_ms`` = -1).
    Either way a session that loses its router reconnects on the :data:`CONNECT_RETRY`
    schedule, forever.

    Credentials (docs/security.md): from the folder ``security``, else the one found for
    ``endpoints`` (services/security/context.py); with one, the session authenticates as
    ``identity`` (else ``ROCO_IDENTITY``, else ``operator``) with its user name and password
    and, on ``tls/`` endpoints, its certificate (mutual TLS, checked against the folder's CA).
    Raises services.security.folder.CredentialError (a ValueError) when the folder has no
    credentials for that identity.

    Zenoh's shared-memory transport is off (:func:`_no_shared_memory`), and the process gets
    roco's client runtime pools (:func:`use_runtime_pools`: sets ``ZENOH_RUNTIME`` in this
    process's environment unless it is set), for its first session."""
    use_runtime_pools()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps(endpoints))
    conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    conf.insert_json5("scouting/multicast/enabled", "false")
    # every put carries its sender's timestamp: the record's time sent
    conf.insert_json5("timestamping/enabled", "true")
    _no_shared_memory(conf)
    if wait_for_router:
        conf.insert_json5("connect/timeout_ms", "-1")
    folder = security if security is not None else security_for(endpoints)
    if folder is not None:
        _client_auth(conf, folder, identity_name(identity))
    return conf


def _client_auth(conf: zenoh.Config, folder: Path, identity: str, *, serve: bool = False) -> None:
    """Enter ``identity``'s user name, password and certificate (to connect; ``serve``: also
    to accept, as a peer does) of ``folder`` in ``conf``."""
    from services.security.folder import identity as load_identity

    ident = load_identity(folder, identity)
    conf.insert_json5("transport/auth/usrpwd/user", json.dumps(ident.name))
    conf.insert_json5("transport/auth/usrpwd/password", json.dumps(ident.password))
    tls = {
        "root_ca_certificate": str(ident.ca),
        "connect_private_key": str(ident.key),
        "connect_certificate": str(ident.cert),
        "enable_mtls": True,
    }
    if serve:
        tls |= {"listen_private_key": str(ident.key), "listen_certificate": str(ident.cert)}
    conf.insert_json5("transport/link/tls", json.dumps(tls))


Links = Literal["peer", "router"]
"""How a session on the data path (an agent's) reaches the others (``ROCO_LINKS``):
``router``, a client of the router, every communicate two hops (sender → router → receiver);
``peer``, a Zenoh peer that also links directly to every other peer on its host (one hop), the
router kept for discovery, liveliness, the recorder and the operator's tools. See
:func:`one_hop`."""

LOOPBACK = ("127.0.0.1", "localhost")


def links_setting() -> Links:
    """``ROCO_LINKS`` (read now; default ``peer``)."""
    return Settings.from_env(only=("links",)).links


def one_hop(endpoints: list[str], folder: Path | None) -> bool:
    """Whether sessions to the router at ``endpoints`` may link to each other directly:
    every endpoint is on this host's loopback (peers listen on loopback only: across hosts and
    containers the router path stays), and either there is no access control (no credentials
    ``folder``) or every endpoint is mutual TLS and ``folder`` holds the ACL and the password
    table a peer checks its peers with (a folder of one identity's credentials, as a container
    of deploy/compose.yaml mounts it, keeps the router path). With access control over plain TCP a peer could
    not tell the router's link from another peer's (the opener of a link learns nothing of the
    acceptor's identity without a certificate), so such a fleet keeps the router path."""
    for ep in endpoints:
        proto, _, rest = ep.partition("/")
        host = rest.rsplit(":", 1)[0].strip("[]")
        if proto not in ("tcp", "tls") or host not in LOOPBACK:
            return False
        if folder is not None and proto != "tls":
            return False
    if folder is not None:
        from services.security.folder import ACL_FILE, PASSWORDS

        if not ((folder / ACL_FILE).is_file() and (folder / PASSWORDS).is_file()):
            return False
    return bool(endpoints)


def peer_access_control(acl: dict[str, Any]) -> dict[str, Any]:
    """A peer session's ``access_control`` from the router's (``acl.json``,
    services/spec_check/acl.py): the same rules and policies, each subject matched by its
    certificate's common name only (the opener of a link sees the acceptor's certificate but
    not its user name), and the router (common name ``router``, ``services.security.folder``
    ROUTER) allowed everything on its link: the router applies the full access control to what
    it relays from its clients. So each peer drops what another peer may not send it or it may
    not send that peer, as the router would."""
    from services.security.folder import ROUTER

    rules = list(acl.get("rules", []))
    subjects = [
        {"id": s["id"], "cert_common_names": list(s.get("cert_common_names", s.get("usernames", [])))}
        for s in acl.get("subjects", [])
    ]
    policies = list(acl.get("policies", []))
    rules.append(
        {
            "id": "router/relays",
            "permission": "allow",
            "flows": ["ingress", "egress"],
            "messages": list(ACL_MESSAGES),
            "key_exprs": list(RELAYED),
        }
    )
    subjects.append({"id": "router/link", "cert_common_names": [ROUTER]})
    policies.append({"id": "router/link", "rules": ["router/relays"], "subjects": ["router/link"]})
    return {**acl, "rules": rules, "subjects": subjects, "policies": policies}


RELAYED = ("**", "**/@adv/**")
"""What the router's link may carry to and from a peer: everything (``**`` never matches a
verbatim ``@`` chunk, so zenoh-ext's advanced publishers' caches, tokens and heartbeats below
``<key>/@adv/`` are named apart)."""


def member_config(
    endpoints: list[str],
    *,
    links: Links | None = None,
    wait_for_router: bool = True,
    identity: str | None = None,
    security: Path | None = None,
) -> zenoh.Config:
    """The configuration of a session on the data path (an agent, a benchmark's raw Zenoh end):
    :func:`client_config`, made a peer when ``links`` (None: ``ROCO_LINKS``) is ``peer`` and
    :func:`one_hop` allows it. The peer listens on this host's loopback (port chosen by the
    system, same protocol as the router's endpoint), learns the other peers from the router
    (Zenoh's gossip) and links to them directly; with credentials, it accepts only a peer with
    a certificate of the folder's CA and its password (the folder's dictionary: the fleet's
    processes share the folder on this host) and applies :func:`peer_access_control` to what
    crosses each of its links. Raises as :func:`client_config`; OSError or ValueError when the
    folder's ``acl.json`` is missing or malformed."""
    folder = security if security is not None else security_for(endpoints)
    conf = client_config(endpoints, wait_for_router=wait_for_router, identity=identity, security=folder)
    if (links or links_setting()) != "peer" or not one_hop(endpoints, folder):
        return conf
    proto = endpoints[0].partition("/")[0]
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"{proto}/127.0.0.1:0"]))
    # one of two peers opens their link (the greater Zenoh id): when both opened at once, Zenoh
    # closed both links and linked them no more
    strategy = {"peer": {"to_router": "always", "to_peer": "greater-zid"}}
    conf.insert_json5("scouting/gossip/autoconnect_strategy", json.dumps(strategy))
    if folder is not None:
        from services.security.folder import ACL_FILE, PASSWORDS

        acl = json.loads((folder / ACL_FILE).read_text())
        _client_auth(conf, folder, identity_name(identity), serve=True)
        conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(folder / PASSWORDS)))
        conf.insert_json5("access_control", json.dumps(peer_access_control(acl)))
    return conf


def router_config(
    listen: list[str],
    connect: list[str] | None = None,
    *,
    security: Path | None = None,
    identity: str | None = None,
    lease_ms: int | None = None,
) -> zenoh.Config:
    """A Zenoh router configuration listening on ``listen``, optionally meshed with other
    routers at ``connect`` (reconnected on the :data:`CONNECT_RETRY` schedule when one of them
    restarts); multicast scouting off.

    With a credentials folder ``security`` (services/security/certs.py) the router requires
    user/password authentication (its ``passwords.txt``), serves ``tls/`` endpoints with
    ``router.pem`` and requires a client certificate from the folder's CA (mutual TLS), and
    applies the access control of ``acl.json`` (services/spec_check/acl.py; default deny). Every
    router drops a message above the codec's size limit (``services.runtime.limits``). Raises
    OSError or ValueError when a file is missing or malformed.

    ``identity`` (a router of a mesh, e.g. ``router_robot``; services/security/certs.py
    ``issue_router_identity``): the router serves and connects with that identity's certificate
    (mutual TLS both ways: a meshed router that cannot show a certificate of the folder's CA is
    refused) and authenticates to the routers it connects to with its user/password.
    ``lease_ms``: Zenoh's transport lease (default 10 s): a link silent that long is closed; a
    mesh over an unreliable link sets it longer than the partitions it should ride out.

    Zenoh's shared-memory transport is off (:func:`_no_shared_memory`), and the process keeps
    Zenoh's own runtime pools (:func:`use_router_pools`: drops a ``ZENOH_RUNTIME`` inherited
    from a roco client) for its first session."""
    use_router_pools()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"')
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("scouting/multicast/enabled", "false")
    _no_shared_memory(conf)
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
        conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    # the codec's limit, enforced again where every message passes
    conf.insert_json5("low_pass_filter", json.dumps(low_pass_filter()))
    if security is not None:
        from services.security.folder import ACL_FILE, CA_CERT, PASSWORDS, ROUTER

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
        if identity is not None:
            tls |= _router_identity(conf, security, identity)
        conf.insert_json5("transport/link/tls", json.dumps(tls))
        conf.insert_json5("access_control", json.dumps(acl))
    if lease_ms is not None:
        conf.insert_json5("transport/link/tx/lease", str(int(lease_ms)))
    return conf


def _router_identity(conf: zenoh.Config, folder: Path, name: str) -> dict[str, object]:
    """The TLS settings of a meshed router's own identity (its certificate to serve and to
    connect with), its user/password entered in ``conf``."""
    from services.security.folder import identity as load_identity

    ident = load_identity(folder, name)
    conf.insert_json5("transport/auth/usrpwd/user", json.dumps(ident.name))
    conf.insert_json5("transport/auth/usrpwd/password", json.dumps(ident.password))
    return {
        "listen_private_key": str(ident.key),
        "listen_certificate": str(ident.cert),
        "connect_private_key": str(ident.key),
        "connect_certificate": str(ident.cert),
    }
