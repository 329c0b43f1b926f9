"""The check every benchmark that starts agents makes of its own set-up: nothing it did was
refused, not understood, or counted as a protocol violation by an agent. A benchmark that
fails it prints no figure.

It reads the agents' counters (services/runtime/counters.py; what ``roco status`` shows):
over Zenoh (:func:`check_agents`), from a run folder's ``counters.json``
(:func:`check_run_folder`), or from in-process agents (:func:`check_counters`). A counter in
:data:`TROUBLE` above zero fails it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any


class SetupRefused(RuntimeError):
    """What a benchmark set up was refused, not understood, or is not as it must be: the
    benchmark prints no figure. The message is one line."""


TROUBLE = (
    "rejected",
    "sent.not-understood",
    "received.not-understood",
    "sent.refuse",
    "received.refuse",
    "sent.failure",
    "received.failure",
    "protocol_violations",
    "send_violations",
    "content_violations",
    "handler_errors",
    "behaviour_errors",
)
"""The counters that say something was refused (``rejected``: not-understood sent, with a
``rejected.<reason>`` beside it; refuse), failed, broke its interaction protocol or its
content language, or raised in an agent (services/runtime/agent.py, admission.py, roles.py)."""


def trouble(counters: Mapping[str, int]) -> dict[str, int]:
    """The :data:`TROUBLE` counters above zero in ``counters``, with the ``rejected.<reason>``
    ones that say why, by name."""
    found = {k: v for k, v in counters.items() if v and (k in TROUBLE or k.startswith("rejected."))}
    return dict(sorted(found.items()))


def check_counters(by_agent: Mapping[str, Mapping[str, int]], during: str) -> None:
    """Raise SetupRefused (one line naming each agent's trouble counters) when any agent's
    ``counters`` in ``by_agent`` has :func:`trouble`; ``during`` says what was done (for the
    message)."""
    bad = {agent: t for agent, c in sorted(by_agent.items()) if (t := trouble(c))}
    if bad:
        told = "; ".join(f"{a}: " + ", ".join(f"{k} {v}" for k, v in t.items()) for a, t in bad.items())
        raise SetupRefused(f"{during}: refused, not understood or against the protocol: {told}")


def check_agents(session: Any, agents: Iterable[str], during: str, timeout: float = 10.0) -> None:
    """Ask ``agents`` for their counters over ``session`` (a zenoh.Session on their router)
    and :func:`check_counters` them. Raises SetupRefused also when one does not answer within
    ``timeout`` s (its counters unknown, the check cannot pass)."""
    from services.runtime.counters import ask_counters

    names = list(agents)
    reports = ask_counters(session, names, timeout)
    missing = [a for a in names if a not in reports]
    if missing:
        raise SetupRefused(f"{during}: no counters from {', '.join(missing)} within {timeout:.0f} s")
    check_counters({a: r.counters for a, r in reports.items()}, during)


def check_run_folder(run_dir: Path, during: str) -> None:
    """:func:`check_counters` of the counters a run saved in ``run_dir`` (``counters.json``).
    Raises SetupRefused also when there are none."""
    from services.runtime.counters import read_counters

    try:
        reports = read_counters(run_dir)
    except (OSError, ValueError) as exc:
        raise SetupRefused(f"{during}: no agent counters in {run_dir}: {exc}") from None
    check_counters({a: r.counters for a, r in reports.items()}, during)


def check_fleet(runs_dir: Path, during: str, timeout: float = 10.0) -> None:
    """:func:`check_agents` on every agent of the fleet ``roco up --runs-dir RUNS_DIR`` started
    (those of the specification its run folder keeps: services/runtime/run_folder.py
    ``spec_for_run``), through an operator's session with that fleet's credentials
    (``.fleet.json`` names its endpoint and run folder; the credentials are the run folder's
    ``security``, as ``roco status`` uses them). Raises SetupRefused also when the state or
    the specification cannot be read or the session is refused."""
    import json

    from services.runtime.run_folder import spec_for_run
    from services.runtime.session import SessionRefused, open_operator
    from services.spec.model import load

    try:
        state = json.loads((runs_dir / ".fleet.json").read_text())
        endpoint, run_dir = str(state["endpoint"]), Path(state["run_dir"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SetupRefused(f"{during}: no fleet state in {runs_dir}: {exc}") from None
    try:
        agents = load(spec_for_run(run_dir)).launch_order
    except ValueError as exc:  # SpecError
        raise SetupRefused(f"{during}: {exc}") from None
    security = run_dir / "security"
    try:
        session = open_operator(endpoint, credentials=security if security.is_dir() else None)
    except SessionRefused as exc:
        raise SetupRefused(f"{during}: {exc}") from None
    try:
        check_agents(session, agents, during, timeout)
    finally:
        session.close()
