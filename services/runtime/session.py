"""A tool's Zenoh session on a fleet, and the fleet's white pages (liveliness tokens).

Used by the operator's tools (CLI, scenario runner, tests) and by the containers' health check
(services/runtime/health.py).
"""

from __future__ import annotations

import zenoh

from services.runtime import keys
from services.runtime.transport import client_config


def open_client(
    endpoint: str, *, wait_for_router: bool = False, identity: str | None = None
) -> zenoh.Session:
    """A Zenoh client session for tools (CLI, tests), authenticated as ``identity`` (default
    ``operator``) when the fleet at ``endpoint`` has access control. Raises zenoh.ZError when
    no router answers (or it refuses the credentials)."""
    return zenoh.open(client_config([endpoint], wait_for_router=wait_for_router, identity=identity))


def alive_agents(session: zenoh.Session, timeout: float = 1.0) -> set[str]:
    """Names with a liveliness token under ``roco/alive/*`` (the white pages)."""
    names = set()
    for reply in session.liveliness().get(keys.ALIVE_ALL, timeout=timeout):
        if reply.ok is not None:
            name = keys.alive_agent(str(reply.ok.key_expr))
            if name is not None:
                names.add(name)
    return names
