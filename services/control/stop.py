"""Stop a fleet (``roco down``): the agents' counters kept in its run folder before they stop,
and the compose fleet found, its counters kept and brought down (services/deploy/engine.py)."""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from pathlib import Path

from services.runtime.session import SessionRefused, open_operator
from shared.settings import Settings


class NoComposeFleet(Exception):
    """No compose fleet, or several, run and none is named: the words that say which."""


def keep_fleet_counters(
    endpoint: str, run_dir: Path, names: Collection[str], agents: Callable[[], Collection[str]]
) -> str:
    """Before `roco down` stops a fleet: the counters of its processes ``names`` that are agents
    (``agents()``, read once the router answers) into ``run_dir``'s counters.json (the report's
    "Agents raised" reads them) and what they raised, in words (services/runtime/raised.py; ""
    when nothing). Nothing is saved when no router answers at ``endpoint``."""
    from services.runtime.counters import ask_counters, save_counters
    from services.runtime.raised import raised_by_agent, raised_text

    try:
        session = open_operator(endpoint)
    except SessionRefused:
        return ""
    try:
        known = agents()
        counters = ask_counters(session, [n for n in names if n in known], timeout=5.0)
    finally:
        session.close()
    save_counters(run_dir, counters)
    return raised_text(raised_by_agent({a: r.counters for a, r in counters.items()}), {})


def compose_target(project: str | None, file: Path | None) -> tuple[str, Path]:
    """The compose fleet `roco down --compose` stops: ``project`` (else ``ROCO_COMPOSE_PROJECT``,
    else the one running) and its compose ``file`` (else the running fleet's, else the
    project's deploy/compose.yaml). Raises :class:`NoComposeFleet` when no fleet, or several,
    run and none is named."""
    from services.deploy import engine
    from services.deploy.compose import COMPOSE_FILE

    project = project or Settings.from_env(only=("compose_project",)).compose_project
    if project is not None:
        return project, file or COMPOSE_FILE
    fleets = engine.running_fleets(engine.run_command)
    if len(fleets) != 1:
        running = ", ".join(f.project for f in fleets)
        which = f"compose fleets {running} run" if fleets else "no compose fleet runs"
        raise NoComposeFleet(f"{which}: say which with --project NAME")
    return fleets[0].project, file or fleets[0].file() or COMPOSE_FILE


@dataclass(frozen=True)
class ComposeStopped:
    """A compose fleet brought down: the words that say whether its agents' counters were kept
    (``kept``), and its run folder on this host (None when it is not known)."""

    kept: str
    run_dir: Path | None


def stop_compose(
    project: str,
    file: Path,
    volumes: bool,
    router: str,
    credentials: Path | None,
    agents: Callable[[Path | None], Sequence[str]],
) -> ComposeStopped:
    """`roco down --compose` of compose ``project`` of ``file``: its agents' counters kept
    (``agents(run_dir)`` names them; asked at ``router`` with the operator's ``credentials``,
    else deploy/certs beside ``file``), then ``docker compose down`` (``volumes``: with its
    named volumes). Raises engine.ComposeFailed when a step cannot be done."""
    from services.deploy import engine

    base = engine.base_command(file, project, engine.run_command)
    name = engine.run_name(base, engine.run_command)
    runs = engine.runs_folder(base, engine.run_command)
    run_dir = runs / name if runs is not None and name is not None else None
    kept = save_compose_counters(router, credentials or file.parent / "certs", run_dir, agents(run_dir))
    engine.down(base, volumes, engine.run_command)
    return ComposeStopped(kept, run_dir)


def save_compose_counters(router: str, credentials: Path, run_dir: Path | None, agents: Sequence[str]) -> str:
    """Keep the counters of a compose fleet's ``agents`` in its run folder (the report's
    "Agents raised"); the words that say whether they were kept."""
    from services.runtime.counters import ask_counters, save_counters

    if run_dir is None:
        return ""
    try:
        session = open_operator(router, credentials=credentials if credentials.is_dir() else None)
    except SessionRefused as exc:
        return f" (agents' counters not kept: {exc})"
    try:
        counters = ask_counters(session, agents, timeout=5.0)
    finally:
        session.close()
    try:
        save_counters(run_dir, counters)
    except OSError as exc:
        return f" (agents' counters not kept: {exc.strerror or exc})"
    return f" (counters of {', '.join(sorted(counters)) or 'no agent'} kept)"
