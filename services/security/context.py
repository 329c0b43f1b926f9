"""Which credentials a Zenoh session of this process uses (no cryptography imported here).

A credentials folder (services/security/certs.py) is found for a router endpoint by, in order:

1. :func:`register` — the launcher registers each fleet's ``<run>/security`` for its endpoint,
   so the tools and tests in the same process (``roco run``, the scenario runner) use it;
2. ``ROCO_SECURITY`` — the folder, set for every process a fleet starts and in containers;
3. ``runs/.fleet.json`` in the current directory (the fleet of ``roco up``) when its endpoint is
   the one asked for and its run folder has ``security/``: ``roco send``/``status``/``fault``.

None found: the session does not authenticate (a fleet without access control). The identity is
the one the caller names (an agent's name, ``recorder``), else ``ROCO_IDENTITY``, else
``operator``.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

from shared.settings import Settings

ENV_SECURITY = Settings.env_name("security")
# services/fleet_state.py FLEET_FILE under the default runs dir (this layer cannot import it)
FLEET_FILE = Path("runs") / ".fleet.json"

_lock = threading.Lock()
_registry: dict[str, Path] = {}


def acl_on() -> bool:
    """Whether fleets start with access control (``ROCO_ACL`` is not ``0``; read now)."""
    return Settings.from_env(only=("acl",)).acl


def tls_on() -> bool:
    """Whether local fleets listen on TLS (``ROCO_TLS=1``; read now)."""
    return Settings.from_env(only=("tls",)).tls


def register(endpoint: str, folder: Path | None) -> None:
    """Use credentials ``folder`` for sessions to ``endpoint`` in this process (None: forget)."""
    with _lock:
        if folder is None:
            _registry.pop(endpoint, None)
        else:
            _registry[endpoint] = folder


def security_for(endpoints: list[str]) -> Path | None:
    """The credentials folder for a session to ``endpoints`` (see the module docstring)."""
    with _lock:
        for e in endpoints:
            if e in _registry:
                return _registry[e]
    named = Settings.from_env(only=("security",)).security
    if named is not None:
        return named
    try:
        state = json.loads(FLEET_FILE.read_text())
        if state.get("endpoint") in endpoints:
            folder = Path(state["run_dir"]) / "security"
            if folder.is_dir():
                return folder
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        pass
    return None


def identity_name(identity: str | None) -> str:
    """``identity``, else ``ROCO_IDENTITY`` (read now), else ``operator``."""
    return identity or Settings.from_env(only=("identity",)).identity
