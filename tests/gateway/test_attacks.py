"""The gateway against a careless or hostile peer, in this process: a_hi and a stand-in a_co
on a MemoryBus, the gateway's HTTP server on a loopback port, peers that are
sockets of this test. Each attack is answered with a 4xx (or, for a loop, nothing), counted,
and the next valid message is answered. Costs in CPU and memory of the worst bodies are
measured on a gateway process: tests/gateway/test_worst_bodies.py."""

from __future__ import annotations

import asyncio
import json
import queue
import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from services.bench.gateway import Inbox, acl, body, envelope, message, post, post_now, request
from services.fleet.launcher import free_port
from services.gateway.bounds import Limits
from services.gateway.bridge import Gateway, open_gateway
from services.gateway.http_mtp import decode_body
from services.gateway.server import MTPServer
from services.spec.model import default_spec
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import CommandOutcome
from shared.fipa_codec.string_form import parse
from tests.agents.human_interface.test_agent import TIMEOUT, ScriptedCo, Stage
from tests.support.jade_platform import JADE, JadePlatform

WAIT = 30.0
"""Seconds a test waits for something that comes within milliseconds when all is well."""


@dataclass
class Door:
    """A gateway (``gateway``, ``server``) at ``url`` in front of a_hi and a stand-in a_co, a
    JADE-like platform ``jade`` and an :class:`Inbox` for other peers' answers."""

    stage: Stage
    co: ScriptedCo
    gateway: Gateway
    server: MTPServer
    url: str
    jade: JadePlatform
    inbox: Inbox

    @property
    def address(self) -> tuple[str, int]:
        return ("127.0.0.1", self.server.address[1])

    def valid_message_is_answered(self) -> None:
        """The JADE platform's sentence a_hi cannot read comes back as a_hi's refuse."""
        content = json.dumps({"type": "sentence", "text": "sing me a song"})
        assert self.jade.request(self.url, "a_hi", self.jade.acl("a_hi", content, "C-next")) == 200
        answer = self.jade.next(WAIT)
        assert answer.msg.performative is Performative.REFUSE and answer.msg.sender is not None
        assert answer.msg.sender.name == "a_hi"


@pytest.fixture
def door_with() -> Iterator[Callable[[Limits], Door]]:
    made: list[Door] = []

    def make(limits: Limits) -> Door:
        stage = Stage()
        co = stage.co()
        stage.start_hi()
        assert co.subscribed.wait(TIMEOUT)
        port = free_port()
        url = f"http://127.0.0.1:{port}/acc"
        gateway, server = open_gateway(
            stage.bus.transport(), default_spec(), "127.0.0.1", port, url, limits=limits
        )
        door = Door(stage, co, gateway, server, url, JadePlatform(), Inbox())
        made.append(door)
        return door

    yield make
    for door in made:
        door.jade.close()
        door.inbox.close()
        door.server.stop()
        door.gateway.stop()
        door.stage.stop()


@pytest.fixture
def door(door_with: Callable[[Limits], Door]) -> Door:
    return door_with(Limits())


def raw(address: tuple[str, int], data: bytes) -> bytes:
    """Send ``data`` on a new connection and read until the server closes it."""
    with socket.create_connection(address, timeout=WAIT) as s:
        s.sendall(data)
        out = b""
        while chunk := s.recv(65536):
            out += chunk
    return out


def wait_until(condition: Callable[[], bool], timeout: float = WAIT) -> None:
    """Return once ``condition()`` holds (checked every 10 ms); AssertionError after
    ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "the condition never held"
        time.sleep(0.01)


def status_of(answer: bytes) -> int:
    return int(answer.split(b" ", 2)[1]) if answer.startswith(b"HTTP/") else 0


# ------------------------------------------------------------------------------- loops
def test_an_answer_address_of_roco_is_never_posted_to(door: Door) -> None:
    port = door.server.address[1]
    own = [door.url, f"http://localhost:{port}/acc", f"http://[::1]:{port}/other", f"http://0.0.0.0:{port}/"]
    payload = acl("loop@evil:1099/JADE", "a_co", "x", "c-loop", " ".join(own)).encode()
    data = request(door.url, body(envelope("a_co", "loop@evil:1099/JADE", len(payload)), payload))
    assert post_now(door.address, data) == 200
    door.valid_message_is_answered()
    counters = door.gateway.counters
    assert counters["refused.receiver"] == 1 and counters["post_skipped.roco_address"] == 4
    assert counters["post_failed"] == 1 and counters["received"] == 2  # nothing came back from itself


def test_a_refusal_that_comes_back_as_from_a_roco_agent_is_403_and_not_answered(door: Door) -> None:
    payload = acl("a_co", "a_hi", json.dumps({"type": "sentence", "text": "x"}), "c-own", door.url).encode()
    data = request(door.url, body(envelope("a_hi", "a_co", len(payload)), payload))
    assert post_now(door.address, data) == 403
    for performative in ("REFUSE", "FAILURE", "NOT-UNDERSTOOD"):  # answers are never answered
        text = acl("mallory@evil:1099/JADE", "a_co", "x", f"c-{performative}", door.inbox.address)
        answer = text.replace("(REQUEST", f"({performative}", 1).encode()
        assert (
            post_now(door.address, request(door.url, body(envelope("a_co", "m", len(answer)), answer))) == 200
        )
    door.valid_message_is_answered()
    counters = door.gateway.counters
    assert counters["refused.sender"] == 1 and counters["http.403"] == 1
    assert counters["refused.receiver"] == 3 and not counters["post_failed"]  # none answered
    assert door.inbox.bodies.empty()


# ------------------------------------------------------------------------------- stalls
class Staller:
    """A peer that accepts connections and never reads nor answers."""

    def __init__(self) -> None:
        self.listener = socket.socket()
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(16)
        self.address = f"http://127.0.0.1:{self.listener.getsockname()[1]}/acc"
        self.accepted: queue.SimpleQueue[socket.socket] = queue.SimpleQueue()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            self.accepted.put(conn)

    def close(self) -> None:
        self.listener.close()


def still_open(conn: socket.socket) -> bool:
    """Whether the other end has not closed ``conn`` (nothing to read, no EOF)."""
    conn.setblocking(False)
    try:
        return conn.recv(1, socket.MSG_PEEK) != b""
    except BlockingIOError:
        return True


def test_an_answer_address_that_never_answers_holds_one_post_not_the_gateway(
    door_with: Callable[[Limits], Door],
) -> None:
    door = door_with(Limits(post_s=600.0))
    staller = Staller()
    try:
        data = message(door.url, "slow@evil:1099/JADE", "a_co", "x", "c-slow", staller.address)
        assert post_now(door.address, data) == 200  # refused (a_co): the refuse goes to the staller
        held = staller.accepted.get(timeout=WAIT)
        door.valid_message_is_answered()  # while the staller holds its post
        assert still_open(held)
        held.close()
    finally:
        staller.close()


def test_a_message_listing_many_addresses_is_refused_or_tried_at_a_few() -> None:
    from services.gateway.envelope import Envelope
    from services.gateway.http_mtp import MTPError, MTPMessage
    from services.runtime.memory_transport import MemoryBus
    from shared.fipa_codec import AgentIdentifier

    tried: queue.SimpleQueue[tuple[str, str]] = queue.SimpleQueue()

    async def refused(address: str, message: MTPMessage) -> None:
        tried.put((address, parse(message.payload).conversation_id or ""))
        raise OSError("connection refused")

    gateway = Gateway(MemoryBus().transport(), default_spec(), "http://127.0.0.1:1/acc", post=refused)
    gateway.start()
    try:
        to = (AgentIdentifier("a_co"),)
        many = " ".join(f"http://h{i}.example:7778/acc" for i in range(100_000))
        with pytest.raises(MTPError, match="more than 10000 tokens"):
            gateway.deliver(
                MTPMessage(Envelope(to=to), acl("m@evil", "a_co", "x", "c0", many).encode()), "9.9.9.9"
            )
        ten = " ".join(f"http://h{i}.example:7778/acc" for i in range(10))
        for conversation in ("c1", "c2"):  # in order for one agent: c2's first try follows c1's last
            gateway.deliver(
                MTPMessage(Envelope(to=to), acl("m@evil", "a_co", "x", conversation, ten).encode()), "9.9.9.9"
            )
        attempts = [tried.get(timeout=WAIT) for _ in range(5)]
        assert attempts[:4] == [(f"http://h{i}.example:7778/acc", "c1") for i in range(4)]
        assert attempts[4][1] == "c2"
        assert gateway.counters["post_skipped.over_cap"] >= 6 and gateway.counters["post_failed"] >= 1
    finally:
        gateway.stop()


# ------------------------------------------------------------------------------- HTTP
def test_slow_heads_and_slow_bodies_are_answered_408(door_with: Callable[[Limits], Door]) -> None:
    door = door_with(Limits(header_s=1.0, request_s=1.0))
    assert status_of(raw(door.address, b"POST /acc HTTP/1.1\r\nHost: x\r\n")) == 408
    head = request(door.url, b"x" * 100)[:-100]  # the head, and no body
    assert status_of(raw(door.address, head + b"xx")) == 408
    door.valid_message_is_answered()
    assert door.gateway.counters["http.408"] == 2


@pytest.mark.parametrize(
    ("name", "data", "status"),
    [
        ("no POST", b"GET /acc HTTP/1.1\r\nHost: x\r\n\r\n", 405),
        ("no length", b"POST /acc HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", 411),
        ("chunked", b"POST /acc HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n", 411),
        ("over 8 MiB", b"POST /acc HTTP/1.1\r\nHost: x\r\nContent-Length: 8388609\r\n\r\n", 413),
        (
            "5,000-digit length",
            b"POST /acc HTTP/1.1\r\nHost: x\r\nContent-Length: " + b"9" * 5000 + b"\r\n\r\n",
            400,
        ),
        ("13-digit length", b"POST /acc HTTP/1.1\r\nHost: x\r\nContent-Length: 0000000000001\r\n\r\nx", 400),
        ("no HTTP", b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03" + b"\0" * 64, 400),
        ("100 headers", b"POST /acc HTTP/1.1\r\n" + b"X-a: b\r\n" * 100 + b"\r\n", 431),
        ("a 10 kB header", b"POST /acc HTTP/1.1\r\nX-a: " + b"b" * 10_000 + b"\r\n\r\n", 431),
        ("a 10 kB target", b"POST /" + b"a" * 10_000 + b" HTTP/1.1\r\n\r\n", 431),
        ("not multipart", request("http://h:1/acc", b"hello", content_type="text/plain"), 406),
    ],
)
def test_what_is_no_message_is_one_4xx_counted_and_without_versions(
    door: Door, name: str, data: bytes, status: int
) -> None:
    answer = raw(door.address, data)
    assert status_of(answer) == status, answer[:200]
    head, _, page = answer.partition(b"\r\n\r\n")
    assert b"\nServer: roco\r" in head and b"aiohttp" not in head and b"Python" not in head
    assert page.count(b"\n") == 0 and page.startswith(b"<html><body><h1>%d " % status)
    door.valid_message_is_answered()
    assert door.gateway.counters[f"http.{status}"] == 1


BAD_BODIES = {
    "punycode payload": body(envelope("a_hi", JADE, 4, encoding="punycode"), b"\xff\xfe\xfd\xfc"),
    "idna payload": body(envelope("a_hi", JADE, 4, encoding="idna"), b"a..b"),
    "utf-7 payload": body(envelope("a_hi", JADE, 4, encoding="utf-7"), b"+AGE-"),
    "rot13 payload": body(envelope("a_hi", JADE, 4, encoding="rot13"), b"(x)"),
    "zlib payload": body(envelope("a_hi", JADE, 4, encoding="zlib"), b"(x)"),
    "bad UTF-16": body(envelope("a_hi", JADE, 3, encoding="UTF-16"), b"\x00\xd8a"),
    "uuencoded part": body(
        envelope("a_hi", JADE, 3), b"(x)", payload_headers="Content-Transfer-Encoding: x-uuencode\r\n"
    ),
    "5,000-digit payload-length": body(envelope("a_hi", JADE, "9" * 5000), b"(x)"),
    "5,000-digit params index": body(
        envelope("a_hi", JADE, 3).replace('index="1"', 'index="' + "9" * 5000 + '"'), b"(x)"
    ),
    "a DTD": body('<?xml version="1.0"?><!DOCTYPE envelope><envelope/>', b"(x)"),
    "entity definitions": body(
        '<!DOCTYPE e [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]>'
        "<envelope>&b;</envelope>",
        b"(x)",
    ),
    "an external entity": body(
        '<!DOCTYPE e [<!ENTITY x SYSTEM "file:///etc/passwd">]><envelope>&x;</envelope>', b"(x)"
    ),
    "a 65 kB envelope": body("<envelope>" + " " * 65_536 + "</envelope>", b"(x)"),
    "nine receivers": body(
        envelope("a_hi", JADE, 3).replace(
            "<to>", "<to>" + "<agent-identifier><name>a_hi</name></agent-identifier></to><to>" * 8, 1
        ),
        b"(x)",
    ),
    "8 MiB of '(' as payload": body(
        envelope("a_hi", JADE, 8 * 1024 * 1024 - 2048), b"(" * (8 * 1024 * 1024 - 2048)
    ),
}


@pytest.mark.parametrize("name", BAD_BODIES)
def test_odd_encodings_numbers_and_xml_are_406(door: Door, name: str) -> None:
    assert post_now(door.address, request(door.url, BAD_BODIES[name])) == 406
    door.valid_message_is_answered()
    assert door.gateway.counters["http.406"] == 1 and not door.gateway.counters["internal_errors"]


@pytest.mark.parametrize(
    "content",
    [
        "[" * 30_000 + "]" * 30_000,
        '{"type": "sentence", "text": "x", "y": ' + "[" * 33 + "]" * 33 + "}",
        "x" * 70_000,
    ],
)
def test_deep_or_long_json_content_is_not_understood(door: Door, content: str) -> None:
    assert door.jade.request(door.url, "a_hi", door.jade.acl("a_hi", content, "C-deep")) == 200
    answer = door.jade.next(WAIT)
    assert answer.msg.performative is Performative.NOT_UNDERSTOOD
    assert door.gateway.counters["refused.content"] == 1 and not door.gateway.counters["internal_errors"]
    door.valid_message_is_answered()


# ------------------------------------------------------------------------------- identity
def test_a_foreign_name_in_use_cannot_be_taken_by_another_peer(door_with: Callable[[Limits], Door]) -> None:
    door = door_with(Limits(linger_s=0.0))
    thief = JadePlatform()  # the same name (da0@host:1099/JADE), another address
    try:
        content = json.dumps({"type": "sentence", "text": "bring me the cup"})
        assert door.jade.request(door.url, "a_hi", door.jade.acl("a_hi", content, "C1_jade")) == 200
        request_ = door.co.receive(Performative.REQUEST)  # the conversation is open: a_co has not answered
        cid = request_.msg.conversation_id or ""
        assert thief.request(door.url, "a_hi", thief.acl("a_hi", content, "C1_jade")) == 403
        assert door.gateway.counters["refused.identity"] == 1

        def run(co: ScriptedCo) -> None:
            co.engine.reply(request_, Performative.AGREE)
            outcome = CommandOutcome(command_id=cid, succeeded=True, detail="done")
            co.engine.reply(request_, Performative.INFORM, outcome)

        door.co.do(run)
        answers = [door.jade.next(WAIT).msg.performative for _ in range(2)]
        assert answers == [Performative.AGREE, Performative.INFORM]  # to the first peer, in order
        assert thief.inbox.empty()
        # its conversation over, the name is free again (linger 0 s)
        assert thief.request(door.url, "a_hi", thief.acl("a_hi", content.replace("cup", "song"), "C2")) == 200
    finally:
        thief.close()


# ------------------------------------------------------------------------------- load
def test_a_hundred_peers_at_once_are_all_answered(door: Door) -> None:
    async def all_at_once() -> list[int]:
        data = [
            message(door.url, f"p{i}@many:1099/JADE", "a_co", "x", f"c{i}", door.inbox.address)
            for i in range(100)
        ]
        return await asyncio.gather(*(post(door.address, d) for d in data))

    assert asyncio.run(all_at_once()) == [200] * 100
    answers = [parse(decode_body(*door.inbox.next(WAIT)).payload) for _ in range(100)]
    assert {a.performative for a in answers} == {Performative.REFUSE}
    assert len({a.conversation_id for a in answers}) == 100


def test_idle_connections_beyond_the_cap_get_503_and_the_gateway_goes_on(
    door_with: Callable[[Limits], Door],
) -> None:
    door = door_with(Limits(max_connections=20))
    idle = [socket.create_connection(door.address) for _ in range(20)]
    try:
        with socket.create_connection(door.address) as extra:  # accepted, answered, closed
            extra.settimeout(WAIT)
            assert extra.recv(100).startswith(b"HTTP/1.1 503")
    finally:
        for s in idle:
            s.close()
    wait_until(lambda: door.server.connections == 0)  # the server saw them close
    door.valid_message_is_answered()
    assert door.gateway.counters["http.503"] == 1
