"""A replayed agent whose timer fires a few milliseconds from a peer's token appearing takes the
two in an order the record allows: on the record of tests/replay/fixtures/timer_beside_token (its
README), the replay with the token where the recorder saw it sends a_ta's timer request before
its power-ons subscription (the replayed clock stands still while the agent computes, so its
3-s timer runs 23 ms ahead of the run's) and differs in 1,147 places; with the token taken as
seen by a_ta up to the record's lateness earlier (a token carries no timestamp), the run is
reproduced, and the replay says so (services/replay/driver.py ``_other_orders``)."""

from __future__ import annotations

import json
from pathlib import Path

from services.replay.driver import render, replay

RUN = Path(__file__).parent / "fixtures" / "timer_beside_token"


def test_a_ta_s_timer_and_ag_ex_s_token_are_replayed_in_an_order_the_record_allows() -> None:
    result = replay(RUN, "a_ta")
    assert result.equal, render(result)
    assert any(n.startswith("ag_ex's token taken as seen by a_ta up to ") for n in result.notes), result.notes


def test_the_record_shows_the_subscribe_before_the_timer_s_request() -> None:
    """What the test above asks of the replay, in the record itself: the subscribe is seq 9, the
    timer's request seq 11, both after ag_ex's token."""
    sent = [
        (r["seq"], r["performative"], r["conversation_id"])
        for r in map(json.loads, (RUN / "traffic.jsonl").read_text().splitlines())
        if r["sender"] == "a_ta" and r["receivers"] == ["ag_ex"] and 9 <= r["seq"] <= 11
    ]
    assert [s[:2] for s in sent] == [(9, "subscribe"), (10, "request"), (11, "request")]
    assert sent[0][2] == "ta-power-ons"
