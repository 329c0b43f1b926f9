"""services/recorder/causal.py ``send_order``: a burst of one party's informs recorded before the
other party's confirms that were sent between them is checked in the order they were sent, also
when other conversations' traffic lies between (as in a kinematic fleet's pour, where a_ta's
steps take microseconds)."""

from __future__ import annotations

from dataclasses import dataclass

from services.recorder.causal import SEND_ORDER_REACH, SEND_ORDER_WINDOW, send_order
from services.recorder.record import TrafficRecord
from shared.fipa_codec import Communicate


@dataclass(frozen=True)
class Rec:
    """A recorded communicate with no decoded payload (the ordering reads its record only)."""

    rec: TrafficRecord
    comm: Communicate | None = None


def _rec(seq: int, sender: str, receiver: str, perf: str, t_sent: float, cid: str = "exec1") -> Rec:
    rec = TrafficRecord(
        seq=seq, t=100.0 + seq, size=10, channel="C1", sender=sender, receivers=(receiver,),
        performative=perf, protocol="coordinate", conversation_id=cid, t_sent=t_sent,
    )  # fmt: skip
    return Rec(rec)


def _burst(n: int, noise: int) -> list[Rec]:
    """a_ta's ``n`` informs (sent at 1, 3, 5, …) recorded first, ``noise`` communicates of
    another conversation after them, then a_co's confirms (sent at 2, 4, 6, …)."""
    informs = [_rec(i, "a_ta", "a_co", "inform", 1.0 + 2 * i) for i in range(n)]
    others = [_rec(n + k, "a_pl", "a_km", "query-ref", 0.5, cid="q") for k in range(noise)]
    confirms = [_rec(n + noise + i, "a_co", "a_ta", "confirm", 2.0 + 2 * i) for i in range(n)]
    return informs + others + confirms


def _alternates(ordered: list[Rec]) -> bool:
    mine = [m.rec.performative for m in ordered if m.rec.conversation_id == "exec1"]
    return mine == ["inform", "confirm"] * (len(mine) // 2)


def test_confirms_recorded_after_a_burst_are_put_back_between_the_informs() -> None:
    ordered, moved = send_order(_burst(14, 24))  # 38 places: the run that showed it
    assert _alternates(ordered) and moved == 13
    assert sorted(m.rec.seq for m in ordered) == list(range(14 + 24 + 14))


def test_the_window_counts_the_conversation_and_the_reach_bounds_the_work() -> None:
    assert _alternates(send_order(_burst(SEND_ORDER_WINDOW - 1, 0))[0])
    # more of the conversation between than the window: left as recorded (verify then says so)
    assert not _alternates(send_order(_burst(SEND_ORDER_WINDOW + 2, 0))[0])
    # other traffic beyond the reach: left as recorded
    assert not _alternates(send_order(_burst(2, SEND_ORDER_REACH))[0])
