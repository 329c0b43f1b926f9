"""The ``stage`` fixture of a_hi's tests on an in-memory bus (test_agent.py ``Stage``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.agents.human_interface.test_agent import Stage


@pytest.fixture
def stage(monkeypatch: pytest.MonkeyPatch) -> Iterator[Stage]:
    """A stage of its own, with neither a knowledge store nor a run folder from the environment
    (a real a_km started on it keeps its store in a folder of its own)."""
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    s = Stage()
    try:
        yield s
    finally:
        s.stop()
