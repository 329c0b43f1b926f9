"""What ``roco hosts up`` leaves in the runs folder for the other ``roco hosts`` commands and
``roco down``: the host pair, the run folder, the operator's endpoint and the link's shaping
(``.hosts.json``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import msgspec

if TYPE_CHECKING:
    from services.hosts.netns import HostPair

HOSTS_FILE = ".hosts.json"


class HostsStateError(Exception):
    """No two-host fleet is up in a runs folder, or its state file cannot be read."""


class HostsState(msgspec.Struct):
    """What ``roco hosts up`` leaves for the other ``roco hosts`` commands."""

    tag: str
    subnet: int
    maker: int
    run_dir: str
    endpoint: str
    shaping: str
    how: str

    def pair(self) -> HostPair:
        """The two hosts (network namespaces) this state names."""
        from services.hosts.netns import HostPair

        return HostPair(self.tag, self.subnet, self.maker)


def read_state(runs_dir: Path) -> HostsState:
    """The state ``roco hosts up`` left in ``runs_dir``. Raises :class:`HostsStateError`, in
    words an operator acts on, when there is none or it cannot be read."""
    path = runs_dir / HOSTS_FILE
    try:
        return msgspec.json.decode(path.read_bytes(), type=HostsState)
    except FileNotFoundError:
        raise HostsStateError(f"no two-host fleet is up (no {path}); 'roco hosts up' first") from None
    except (OSError, msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise HostsStateError(f"{path}: not a hosts state file: {str(exc).splitlines()[0]}") from None


def write_state(runs_dir: Path, state: HostsState) -> None:
    """Leave ``state`` in ``runs_dir`` for the other ``roco hosts`` commands."""
    (runs_dir / HOSTS_FILE).write_bytes(msgspec.json.encode(state))
