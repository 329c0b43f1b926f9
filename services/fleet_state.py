"""What ``roco up`` leaves in its runs folder for ``roco down``, ``send``, ``status``,
``fault`` and ``doctor``: the file ``RUNS/.fleet.json`` with the router endpoint, the run
folder and the PID of each process."""

from __future__ import annotations

from pathlib import Path

import msgspec

FLEET_FILE = ".fleet.json"
"""The fleet state file's name under the runs folder (``roco up --runs-dir``)."""


class FleetState(msgspec.Struct):
    """What ``roco up`` leaves for ``roco down``/``send``/``status``: endpoint and PIDs."""

    endpoint: str
    run_dir: str
    pids: dict[str, int]


class FleetStateError(ValueError):
    """A fleet state file that cannot be read; the message is one line naming the file."""


def read_state(runs_dir: Path) -> FleetState | None:
    """The state of the fleet ``roco up`` started under ``runs_dir``; None when no fleet is up
    there. Raises FleetStateError for a file that is not a fleet state file."""
    path = runs_dir / FLEET_FILE
    if not path.exists():
        return None
    try:
        return msgspec.json.decode(path.read_bytes(), type=FleetState)
    except (msgspec.DecodeError, msgspec.ValidationError, OSError) as exc:
        why = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise FleetStateError(f"{path}: not a fleet state file: {why}") from None


def write_state(runs_dir: Path, state: FleetState) -> None:
    """Write ``state`` as the fleet state file under ``runs_dir``."""
    (runs_dir / FLEET_FILE).write_bytes(msgspec.json.encode(state))
