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
from services.runtime.transport import client_config, open_session
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
    cannot read (services/runtime/transport.py ``open_session``)."""
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
        if not listening(endpoint):
            raise SessionRefused(f"no router answers at {endpoint}; is the fleet up?") from None
        if folder is None:
            raise SessionRefused(
                f"the router at {endpoint} refused the session for want of credentials: "
                f"give the deployment's credentials folder with {CREDENTIALS_HINT}"
            ) from None
        raise SessionRefused(
            f"the router at {endpoint} refused the credentials of {identity_name(identity)!r} from "
            f"{folder} (another deployment's, revoked, or the router wants tls/)"
        ) from None


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


def alive_agents(session: zenoh.Session, timeout: float = 1.0) -> set[str]:
    """Names with a liveliness token under ``roco/alive/*`` (the white pages)."""
    names = set()
    for reply in session.liveliness().get(keys.ALIVE_ALL, timeout=timeout):
        if reply.ok is not None:
            name = keys.alive_agent(str(reply.ok.key_expr))
            if name is not None:
                names.add(name)
    return names
