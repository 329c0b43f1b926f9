"""The peers a replayed agent sees (services/replay/presence.py), from a presence record."""

from __future__ import annotations

from services.recorder.presence import PresenceEvent
from services.replay.presence import Change, lag_of, timeline


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


def test_across_a_link_a_change_is_taken_as_early_as_the_agent_saw_it() -> None:
    """The recorder on another host sees ag_ex's token 60 ms after a_ta (beside ag_ex) did, as it
    sees a_ta's communicates 60 ms after they were sent: the change is taken at a_ta's time, before
    a_ta's timer at 3.055 s (seen in test_two_hosts: the replayed a_ta's timer went first)."""
    events = [_e("a_km", True, 1.0, snapshot=True), _e("ag_ex", True, 3.06)]
    lag = lag_of([0.0, 0.061, 0.060, 0.075])  # a copy from a cache (0) is no delay
    assert lag == 0.060
    peers = timeline(events, "a_ta", start=0.5, agents=[], lag=lag)
    (change,) = peers.changes
    assert change.name == "ag_ex" and change.t < 3.055
    assert timeline(events, "a_ta", start=0.5, agents=[]).changes[0].t == 3.06  # on one host
