"""When each process was away, read from a presence record (services/recorder/presence.py
``absences``, ``away_between``): a token's disappearance and return, a recorder incarnation's
snapshot after a time no recorder watched, and a process that started after the record began."""

from __future__ import annotations

import math

from services.recorder.presence import PresenceEvent, absences, away_between


def ev(name: str, alive: bool, t: float, incarnation: str = "r1", snapshot: bool = False) -> PresenceEvent:
    return PresenceEvent(name=name, alive=alive, t=t, seq=0, incarnation=incarnation, snapshot=snapshot)


def test_a_token_that_went_and_came_back_is_away_between() -> None:
    spans = absences([ev("a_km", True, 1, snapshot=True), ev("a_km", False, 5), ev("a_km", True, 7)])
    assert spans == {"a_km": [(5, 7)]}
    assert away_between(spans["a_km"], 6, 6) == (5, 7)
    # sent before it went and not answered before it came back: away in between
    assert away_between(spans["a_km"], 4, 6) == (5, 7) and away_between(spans["a_km"], 6, 9) == (5, 7)
    assert away_between(spans["a_km"], 4, 4.9) is None and away_between(spans["a_km"], 7.1, 9) is None


def test_in_the_first_snapshot_a_process_was_there_from_the_start_and_a_later_one_was_not() -> None:
    spans = absences([ev("a_hi", True, 1, snapshot=True), ev("a_ta", True, 3)])
    assert spans == {"a_ta": [(-math.inf, 3)]}


def test_between_two_recorder_incarnations_an_absence_is_as_wide_as_the_record_allows() -> None:
    """a_pl is not in the second incarnation's snapshot: gone since the first one's last event,
    back when its token appears; a_co went while no recorder watched and is back in it."""
    events = [
        ev("a_pl", True, 1, snapshot=True),
        ev("a_co", True, 1, snapshot=True),
        ev("a_co", False, 4),
        ev("a_co", True, 12, "r2", snapshot=True),
        ev("a_pl", True, 15, "r2"),
        ev("a_co", False, 20, "r2"),
    ]
    assert absences(events) == {"a_co": [(4, 12), (20, math.inf)], "a_pl": [(4, 15)]}
