"""The peers a replayed agent sees (services/replay/presence.py), from a presence record."""

from __future__ import annotations

from services.recorder.presence import PresenceEvent
from services.replay.presence import Change, timeline


def _e(name: str, alive: bool, t: float, inc: str = "r1", snapshot: bool = False) -> PresenceEvent:
    return PresenceEvent(name=name, alive=alive, t=t, seq=0, incarnation=inc, snapshot=snapshot)


def test_the_first_snapshot_is_alive_from_the_start_and_later_tokens_appear_at_their_time() -> None:
    events = [
        _e("a_km", True, 5.0, snapshot=True),
        _e("a_ta", True, 5.0, snapshot=True),
        _e("recorder", True, 5.1),
        _e("ag_ex", True, 9.0),
        _e("a_km", False, 12.0),
        _e("a_km", True, 13.0),
    ]
    peers = timeline(events, "a_ta", start=8.0, agents=[])
    assert peers.initial == {"a_km", "recorder"}  # a_ta's own token is never a peer's
    assert peers.changes == [
        Change(9.0, "ag_ex", True),
        Change(12.0, "a_km", False),
        Change(13.0, "a_km", True),
    ]


def test_a_later_recorder_s_snapshot_says_what_changed_while_none_watched() -> None:
    events = [
        _e("a_km", True, 1.0, snapshot=True),
        _e("ag_ex", True, 2.0),
        # recorder r1 killed; a_km restarted, ag_ex gone meanwhile; r2 starts at 20 s
        _e("a_km", True, 20.0, inc="r2", snapshot=True),
        _e("a_pl", True, 20.0, inc="r2", snapshot=True),
    ]
    peers = timeline(events, "a_ta", start=0.5, agents=[])
    assert peers.initial == {"a_km"}
    assert peers.changes == [
        Change(2.0, "ag_ex", True),
        Change(20.0, "ag_ex", False),
        Change(20.0, "a_pl", True),
    ]


def test_without_a_presence_record_every_other_agent_is_alive_from_the_start() -> None:
    peers = timeline(None, "a_ta", start=0.0, agents=["a_co", "a_ta", "ag_ex"])
    assert peers.initial == {"a_co", "ag_ex"} and not peers.changes and not peers.recorded
