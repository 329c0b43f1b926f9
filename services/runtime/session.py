"""A tool's Zenoh session on a fleet, and the fleet's white pages (liveliness tokens).

Used by the operator's tools (CLI, scenario runner, tests) and by the containers' health check
(services/runtime/health.py). :func:`open_operator` is the CLI's: it takes the operator's
credentials folder and says in one line why a session could not be opened (no router, refused
for want of credentials, refused credentials; docs/security.md).
"""

from __future__ import annotations

import socket
from pathlib import Path

import zenoh

from services.runtime import keys
from services.runtime.zenoh_config import client_config, open_session
from services.security.context import ENV_SECURITY, identity_name, register, security_for
from services.security.folder import CredentialError

CREDENTIALS_HINT = f"--credentials DIR or {ENV_SECURITY}=DIR"
"""How an operator gives a tool the deployment's credentials folder (docs/security.md)."""


class SessionRefused(RuntimeError):
    """A tool's session could not be opened; the message is one line for the person: no router
    listens, it refused the session for want of credentials (and how to give them), it refused
    the credentials given, or the folder lacks the identity."""


def open_client(
    endpoint: str, *, wait_for_router: bool = False, identity: str | None = None
) -> zenoh.Session:
    """A Zenoh client session for tools (CLI, tests), authenticated as ``identity`` (default
    ``operator``) when the fleet at ``endpoint`` has access control. Raises zenoh.ZError when
    no router answers (or it refuses the credentials); ValueError for a ``ZENOH_RUNTIME`` Zenoh
    cannot read (services/runtime/zenoh_config.py ``open_session``)."""
    return open_session(client_config([endpoint], wait_for_router=wait_for_router, identity=identity))


def open_operator(
    endpoint: str, *, credentials: Path | None = None, identity: str | None = None
) -> zenoh.Session:
    """:func:`open_client` for the operator's tools (``roco send``/``status``/``sniff``/``fault``),
    with ``credentials`` (a credentials folder) registered for ``endpoint`` first when given;
    else they are found as services/security/context.py says (``ROCO_SECURITY``, the fleet of
    ``roco up``). Raises :class:`SessionRefused` with one line saying why."""
    if credentials is not None:
        if not credentials.is_dir():
            raise SessionRefused(f"{credentials}: no such credentials folder")
        register(endpoint, credentials)
    folder = security_for([endpoint])
    try:
        return open_client(endpoint, identity=identity)
    except CredentialError as exc:
        raise SessionRefused(str(exc)) from None
    except zenoh.ZError:
        raise SessionRefused(refusal(endpoint, identity, folder)) from None


def no_router(endpoint: str) -> str:
    """The line for a tool that found no router at ``endpoint``: what it could not reach and how
    to get one (a fleet of ``roco up``, or the router of another one named with ``--router``)."""
    return f"no router answers at {endpoint}: start a fleet with 'roco up', or name its router with --router"


def refusal(endpoint: str, identity: str | None, folder: Path | None) -> str:
    """Why a session as ``identity`` (None: ``operator``) with credentials from ``folder`` (None:
    none found) could not be opened at ``endpoint``, in one line: no router listens there
    (:func:`no_router`), it wants credentials (and how to give them), or it refused those
    given."""
    if not listening(endpoint):
        return no_router(endpoint)
    if folder is None:
        return (
            f"the router at {endpoint} refused the session for want of credentials: "
            f"give the deployment's credentials folder with {CREDENTIALS_HINT}"
        )
    return (
        f"the router at {endpoint} refused the credentials of {identity_name(identity)!r} from "
        f"{folder} (another deployment's, revoked, or the router wants tls/)"
    )


def port_in_use(host: str, port: int, option: str) -> str:
    """The line for a port something listens on already (``listening``): the address, and the
    command's ``option`` that chooses another (``roco up --port``, ``roco view --web-port``)."""
    return f"cannot listen on {host}:{port}: the port is in use; choose another with {option}"


def listening(endpoint: str, timeout: float = 1.0) -> bool:
    """Whether something accepts a TCP connection at ``endpoint``'s address
    (``tcp/HOST:PORT``, ``tls/HOST:PORT``, ``[v6]`` hosts too); False for other protocols."""
    proto, _, address = endpoint.partition("/")
    host, _, port = address.partition("?")[0].rpartition(":")
    if proto not in ("tcp", "tls") or not port.isdigit():
        return False
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            return True
    except OSError:
        return False


def alive_agents(session: zenoh.Session, timeout: float = 1.0, only: str | None = None) -> set[str]:
    """Names with a liveliness token under ``roco/alive/*`` (the white pages); ``only``: ask
    for ``roco/alive/<only>`` alone (the most an identity other than the operator may ask,
    services/spec_check/acl.py)."""
    names = set()
    key = keys.ALIVE_ALL if only is None else keys.alive_key(only)
    for reply in session.liveliness().get(key, timeout=timeout):
        if reply.ok is not None:
            name = keys.alive_agent(str(reply.ok.key_expr))
            if name is not None:
                names.add(name)
    return names
