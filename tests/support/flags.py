"""A live requirement flag (services/recorder/flags.py) for tests that plant one."""

from __future__ import annotations

from services.recorder.flags import LiveFlag


def a_flag(**fields: object) -> LiveFlag:
    """R3.3 flagged at a_ta's Preempted; ``fields`` replace any of its fields."""
    base: dict[str, object] = {
        "requirement": "R3.3",
        "prop": "p",
        "event": "C1 a_ta → a_co inform",
        "why": "w",
        "t": 0.0,
        "seq": 5,
        "recorded": 6,
        "flagged": 0.0,
    }
    return LiveFlag(**{**base, **fields})  # type: ignore[arg-type]
