"""The sorting cell (examples/sorting_cell/) as the tools find a fleet of it, without starting
one: the state file ``roco up`` leaves (``RUNS/.fleet.json``) naming a run folder whose
``launch_env.json`` keeps the cell's specification, as a fleet of ``roco up --spec cell.toml``
leaves them. Its router endpoint answers nothing: a command that gets past the specification
stops at the router."""

from __future__ import annotations

import json
from pathlib import Path

from services.fleet.launcher import free_port
from services.fleet_state import FleetState, write_state
from services.runtime.run_folder import LAUNCH_ENV
from shared.settings import Settings

CELL = Path(__file__).resolve().parents[2] / "examples" / "sorting_cell" / "cell.toml"
"""The sorting cell's specification: agents a_cv, a_so, a_op (start order), channels C1, C2."""
CELL_AGENTS = ("a_cv", "a_so", "a_op")


def cell_fleet(runs_dir: Path) -> Path:
    """Make ``runs_dir`` hold the state of a fleet of the cell (no process of it runs); its run
    folder."""
    run_dir = runs_dir / "20260101-000000"
    run_dir.mkdir(parents=True)
    (run_dir / LAUNCH_ENV).write_text(json.dumps({Settings.env_name("spec"): str(CELL)}))
    write_state(runs_dir, FleetState(f"tcp/127.0.0.1:{free_port()}", str(run_dir), {}))
    return run_dir
