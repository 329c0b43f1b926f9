"""The check an end-to-end test makes of a run folder: no agent raised (services/runtime/raised.py)."""

from __future__ import annotations

from pathlib import Path

from services.runtime.counters import read_counters
from services.runtime.raised import raised_by_agent, raised_text
from services.runtime.run_folder import read_run_info


def assert_no_agent_raised(run_dir: Path, agents: tuple[str, ...]) -> None:
    """Raise AssertionError (naming what was raised, and where to look) unless every one of
    ``agents`` left its counters in ``run_dir``'s counters.json with ``handler_errors`` and
    ``behaviour_errors`` 0, and run.json names no agent that exited by itself."""
    counters = read_counters(run_dir)
    missing = [a for a in agents if a not in counters]
    assert not missing, f"no counters of {', '.join(missing)} in {run_dir}"
    found = raised_by_agent({a: r.counters for a, r in counters.items()})
    crashed = read_run_info(run_dir).crashed
    assert not found and not crashed, f"{raised_text(found, crashed)} (run folder {run_dir})"
