"""The peers a replayed agent sees (services/replay/presence.py), from a presence record."""

from __future__ import annotations

from services.recorder.presence import PresenceEvent
from services.replay.presence import Change, lag_of, timeline
from services.replay.record import Paths


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


def test_on_two_hosts_a_change_is_taken_when_the_agent_saw_it_by_where_the_token_s_owner_ran() -> None:
    """a_ta beside ag_ex on the robot's host, the recorder beside a_co on the brain's, 20 ms apart:
    the recorder sees ag_ex's token 20 ms after a_ta did, and a_co's 20 ms before a_ta did."""
    paths = Paths({"a_ta": "robot", "ag_ex": "robot", "recorder": "brain", "a_co": "brain"}, 0.020)
    events = [_e("a_km", True, 1.0, snapshot=True), _e("ag_ex", True, 3.06), _e("a_co", True, 5.0)]
    peers = timeline(events, "a_ta", start=0.5, agents=[], paths=paths)
    assert [(c.name, round(c.t, 6)) for c in peers.changes] == [("ag_ex", 3.04), ("a_co", 5.02)]
    on_one = timeline(events, "a_ta", start=0.5, agents=[], paths=Paths())
    assert [c.t for c in on_one.changes] == [3.06, 5.0]


def test_a_token_appears_no_later_than_the_first_communicate_to_its_owner_it_may_have_caused() -> None:
    """The recorder saw ag_ex's token at 9.0 s, 4 ms after a_ta's subscription to it (the
    recorder is up to 50 ms late): the token is taken at the subscription. Not so for a
    communicate to ag_ex an input explains (a_ta's answer to a_km's subscription came just
    before it), nor for one before the 50 ms the recorder may lag behind."""
    events = [_e("a_km", True, 1.0, snapshot=True), _e("ag_ex", True, 9.0)]

    def taken(sent: list[float], came: list[float]) -> float:
        peers = timeline(
            events, "a_ta", start=0.5, agents=[], paths=Paths(), sent={"ag_ex": sent}, came=came, window=0.05
        )
        (change,) = peers.changes
        return change.t

    assert taken([6.0, 8.996, 8.999], [6.0]) == 8.996
    assert taken([6.0, 8.996], [6.0, 8.990]) == 9.0  # a_km's input at 8.990 explains it
    assert taken([6.0, 8.9], [6.0]) == 9.0  # 100 ms before: the token was not yet there
    assert taken([6.0, 9.002], [6.0]) == 9.0  # after: it changes nothing


def test_a_token_is_not_taken_to_reappear_before_it_went_away() -> None:
    """ag_ex went away at 8.99 s and came back at 9.0 s; a_ta's request to it at 8.985 s (when
    it was still there) cannot have been caused by its coming back."""
    events = [_e("ag_ex", True, 1.0, snapshot=True), _e("ag_ex", False, 8.99), _e("ag_ex", True, 9.0)]
    peers = timeline(
        events, "a_ta", start=0.5, agents=[], paths=Paths(), sent={"ag_ex": [8.985]}, came=[], window=0.05
    )
    assert peers.changes == [Change(8.99, "ag_ex", False), Change(8.99, "ag_ex", True)]
