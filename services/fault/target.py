"""The fleet a ``roco fault`` command acts on: the local fleet of ``roco up`` or a compose fleet
(the one named, else the one running), the router it is reached at, and the traffic recorder
the faults applied are handed to (services/fault/process.py ``record_events``)."""

from __future__ import annotations

from pathlib import Path

from services.deploy.engine import ComposeFleet, running_fleets
from services.fault import process
from services.fault.compose import DEFAULT_FILE, Compose
from services.fault.process import FaultError, UpFleet
from services.fleet_state import FLEET_FILE
from services.runtime.faults import FaultEvent
from shared.settings import Settings


class SeveralFleets(Exception):
    """Several compose fleets run and none is named: the words that say so."""


def compose_target(
    flag: bool | None, project: str | None, file: Path | None, runs_dir: Path
) -> Compose | None:
    """The compose fleet a fault command acts on, None for the local fleet of ``roco up``.
    Without ``--compose/--local`` (``flag`` None) and ``ROCO_COMPOSE_PROJECT``: the local fleet
    when ``runs_dir`` holds one, else the compose fleet that runs (several: raises
    :class:`SeveralFleets`; none: local, whose error says to start one or add ``--compose``)."""
    named = project or Settings.from_env(only=("compose_project",)).compose_project
    if _local(flag, named, runs_dir):
        return None
    if named is not None:
        return Compose(file=file or DEFAULT_FILE, project=named, state_dir=runs_dir)
    running = _the_running_fleet()
    if running is not None:
        return _compose_of(running, file, runs_dir)
    return Compose(file=file or DEFAULT_FILE, state_dir=runs_dir) if flag else None


def _local(flag: bool | None, named: str | None, runs_dir: Path) -> bool:
    """Whether the local fleet is meant: ``--local``, or neither flag nor project given and
    ``runs_dir`` holds the state of ``roco up``'s fleet."""
    return flag is False or (flag is None and named is None and (runs_dir / FLEET_FILE).exists())


def _the_running_fleet() -> ComposeFleet | None:
    """The one compose fleet that runs (services/deploy/engine.py), None when none does.
    Raises :class:`SeveralFleets` when several do."""
    fleets = running_fleets()
    if len(fleets) > 1:
        names = ", ".join(f.project for f in fleets)
        raise SeveralFleets(f"compose fleets {names} run: say which with --compose --project NAME")
    return fleets[0] if fleets else None


def _compose_of(fleet: ComposeFleet, file: Path | None, runs_dir: Path) -> Compose:
    """The running ``fleet``: its project, and the first of its compose files that is on this
    host unless ``file`` is given."""
    return Compose(file=file or fleet.file() or DEFAULT_FILE, project=fleet.project, state_dir=runs_dir)


def router_endpoint(router: str | None, runs_dir: Path) -> str:
    """The router endpoint: ``router``, else the fleet of ``roco up`` in ``runs_dir``, else
    ``ROCO_ROUTER``."""
    if router:
        return router
    try:
        return UpFleet.load(runs_dir).endpoint
    except FaultError:
        return ",".join(Settings.from_env(only=("router",)).router)


def record(endpoint: str, events: list[FaultEvent]) -> str | None:
    """Hand ``events`` to the traffic recorder of the fleet at ``endpoint``; None once it
    confirmed them, else the words that say why they are not recorded (a warning, not a
    failure)."""
    from services.runtime.session import SessionRefused, alive_agents, open_operator

    try:
        session = open_operator(endpoint)
    except SessionRefused as exc:
        return f"(fault not recorded: {exc})"
    try:
        if "recorder" not in alive_agents(session, timeout=0.5):
            return "(fault not recorded: the traffic recorder is not alive)"
        if not process.record_events(session, events):
            return "(the traffic recorder did not confirm the fault event)"
    finally:
        session.close()
    return None
