"""The foreign agent roco's tools play (services/gateway/platform.py): its request is an HTTP
MTP post another platform reads, naming the address where answers go, and what is posted to
it is handed over."""

from __future__ import annotations

import json
import queue

import pytest

from services.fleet.launcher import free_port
from services.gateway.http_mtp import MTPError
from services.gateway.platform import NAME, ForeignPlatform
from shared.fipa_codec import Communicate, Performative


def test_a_request_reaches_another_platform_with_the_address_for_the_answers() -> None:
    """One platform posts to the other's address as it would post to the gateway: the other
    reads a fipa-request of a Sentence, whose sender names the first platform's address."""
    got: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    receiving = ForeignPlatform(free_port(), got.put, name="other@127.0.0.1/platform")
    asking = ForeignPlatform(free_port(), lambda msg: None)
    receiving.start()
    asking.start()
    try:
        first = asking.request(receiving.address, "a_hi", "pour the jar into the bowl")
        second = asking.request(receiving.address, "a_hi", "what are you doing?")
        one, two = got.get(timeout=10), got.get(timeout=10)
    finally:
        asking.stop()
        receiving.stop()
    assert first != second and {one.conversation_id, two.conversation_id} == {first, second}
    msg = one if one.conversation_id == first else two
    assert msg.performative is Performative.REQUEST and msg.protocol == "fipa-request"
    assert (msg.language, msg.ontology, msg.reply_with) == ("L_HC", "O_RoCo", f"{first}-r1")
    assert msg.sender is not None and msg.sender.name == NAME
    assert msg.sender.addresses == (asking.address,)
    assert [r.name for r in msg.receiver] == ["a_hi"]
    assert json.loads(msg.content) == {"type": "sentence", "text": "pour the jar into the bowl"}
    assert receiving.counts == {"http.200": 2}


def test_a_post_nobody_takes_raises() -> None:
    """An address where nothing listens: OSError (aiohttp's connection error is one); a page
    that is not an MTP server's 200 would be MTPError."""
    asking = ForeignPlatform(free_port(), lambda msg: None)
    with pytest.raises((OSError, MTPError)):
        asking.request(f"http://127.0.0.1:{free_port()}/acc", "a_hi", "stop")
