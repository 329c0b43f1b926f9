"""A real agent (a_km) receiving communicates corrupted by the sender's fault layer answers
them with not-understood and keeps serving."""

from __future__ import annotations

import queue
import threading

import pytest

from services.agents.knowledge.agent import KnowledgeManager
from services.runtime import keys
from services.runtime.faults import FaultSettings, FaultUpdate, FaultyTransport, MessageFaults
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Communicate, DecodeError, Performative, decode, encode
from shared.fipa_codec.languages.l_wm import ObjectQuery
from tests.support.messages import communicate

KEY = keys.fipa_key("C4", "a_pl", "a_km")
SENT = 150


def query(n: int) -> bytes:
    msg = communicate(
        Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", f"c{n}", ObjectQuery("jar"), reply_with=f"q{n}"
    )
    return encode(msg)


def test_corrupted_communicates_get_not_understood_and_the_agent_keeps_running(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    bus = MemoryBus()
    replies: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    bus.subscribe(keys.fipa_key("C4", "a_km", "a_pl"), lambda _k, p: replies.put(p))
    km = KnowledgeManager(bus.transport())
    km.engine.bind()
    thread = threading.Thread(target=km.engine.run, name="a_km", daemon=True)
    thread.start()
    pl = FaultyTransport(
        bus.transport(),
        "a_pl",
        FaultSettings(seed=11, channels={"C4": MessageFaults(corrupt=1.0)}),
        control=False,
    )
    try:
        for n in range(SENT):
            pl.publish(KEY, query(n))
        assert pl.applied["corrupt"] == SENT
        pl.update(FaultUpdate(clear_channels=["*"]))
        pl.publish(KEY, query(SENT))  # a_km takes its inputs in order: this one is answered last
        got: list[Communicate] = []
        while True:
            reply = decode(replies.get(timeout=30))
            got.append(reply)
            if reply.in_reply_to == f"q{SENT}":
                break
        assert got[-1].performative is Performative.INFORM_REF  # still serving
        assert thread.is_alive()
        not_understood = [r for r in got if r.performative is Performative.NOT_UNDERSTOOD]
        # 1–3 flipped bytes almost always break the communicate, its content or its protocol: a
        # not-understood, or (a query that still reads, about a name that is no more) a failure
        # or refuse as FIPA says (SC00027); a copy of a conversation a_km had answered already
        # (a flipped byte in its id) is answered again: which of these depends on the timing
        refused = (Performative.NOT_UNDERSTOOD, Performative.FAILURE, Performative.REFUSE)
        answered_no = [r for r in got if r.performative in refused]
        assert len(answered_no) >= SENT / 2, [r.content for r in got if r not in answered_no]
        assert km.counters["rejected"] == len(not_understood)
        reasons = {r.content.decode().split(":")[0] for r in not_understood}
        assert "malformed communicate" in reasons
    finally:
        km.engine.stop()
        thread.join(timeout=10)
        pl.close()
        km.close()
    assert not thread.is_alive()


def test_a_corrupted_payload_is_often_undecodable() -> None:
    """The corruption itself: mostly not a communicate any more, never the original bytes."""
    import random

    from services.runtime.faults import corrupt_bytes

    rng = random.Random(3)
    original = query(1)
    undecodable = 0
    for _ in range(500):
        bad = corrupt_bytes(original, rng)
        assert bad != original and len(bad) == len(original)
        try:
            decode(bad)
        except DecodeError:
            undecodable += 1
    assert undecodable > 100
