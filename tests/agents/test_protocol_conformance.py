"""Every conversation of a pour follows its interaction protocol's state machine (FIPA
SC00026/27/35 and the paper's coordinate protocol, Figure 8), checked on the traffic."""

from __future__ import annotations

from collections import defaultdict

from shared.fipa_codec import Communicate, decode
from tests.support.conversation import Walk, known_protocols
from tests.support.memory_fleet import MemoryFleet


def test_every_conversation_of_a_pour_follows_its_protocol() -> None:
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        fleet.command("pour the jar into the bowl")
        published = list(fleet.bus.published)
    conversations: dict[str, list[Communicate]] = defaultdict(list)
    for key, payload in published:
        if key.startswith("roco/fipa/"):
            msg = decode(payload)
            assert msg.protocol in known_protocols(), msg.protocol
            assert msg.conversation_id
            conversations[msg.conversation_id].append(msg)
    protocols_seen = set()
    for cid, msgs in conversations.items():
        tracker = Walk(msgs[0].protocol or "")
        for msg in msgs:
            tracker.observe(msg)  # raises ProtocolViolation on a step outside the protocol
        protocols_seen.add(msgs[0].protocol)
        if msgs[0].protocol != "fipa-subscribe":  # the environment subscription stays open
            assert tracker.is_finished, (cid, [m.performative.value for m in msgs])
    assert protocols_seen == {"fipa-request", "fipa-query", "fipa-subscribe", "coordinate"}
