"""The HTTP message transport (FIPA SC00084; services/gateway/http_mtp.py): the body as JADE
writes it, a server that answers as JADE does and keeps running after bad input."""

from __future__ import annotations

import base64
import queue
from collections import Counter
from collections.abc import Iterator

import pytest

from services.fleet.launcher import free_port
from services.gateway.envelope import Envelope
from services.gateway.http_mtp import MTPError, MTPMessage, decode_body, encode_body, post_message
from services.gateway.server import MTPServer
from shared.fipa_codec import AgentIdentifier
from tests.support.jade_platform import BOUNDARY, JADE, JadePlatform, envelope_xml, jade_body, post

ACL = b'(request :sender (agent-identifier :name da0@host:1099/JADE) :content "hi")'


def test_the_body_jade_writes_decodes() -> None:
    body = jade_body(envelope_xml("a_hi", JADE, "http://h:1/acc", len(ACL)), ACL)
    message = decode_body(f'multipart/mixed ; boundary="{BOUNDARY}"', body)
    assert message.payload == ACL
    assert message.envelope.to == (AgentIdentifier("a_hi"),)


def test_encode_then_decode_is_the_message_with_its_length() -> None:
    env = Envelope(to=(AgentIdentifier("a_hi"),), payload_encoding="UTF-8")
    payload = '(inform :content "déjà\r\nvu")'.encode()
    content_type, body = encode_body(MTPMessage(env, payload))
    assert content_type.startswith('multipart/mixed ; boundary="')
    assert body.startswith(b"This is not part of the MIME multipart encoded message.\r\n--")
    back = decode_body(content_type, body)
    assert back.payload == payload and back.envelope.payload_length == len(payload)


@pytest.mark.parametrize(
    ("content_type", "body", "message"),
    [
        ("text/plain", b"hello", "not multipart/mixed"),
        ("multipart/mixed", b"x", "without a boundary"),
        (
            f'multipart/mixed; boundary="{BOUNDARY}"',
            b"--" + BOUNDARY.encode() + b"--\r\n",
            "expected 2 parts",
        ),
        (f'multipart/mixed; boundary="{BOUNDARY}"', jade_body("<nope", ACL), "not XML"),
    ],
)
def test_what_is_no_message_is_an_mtp_error(content_type: str, body: bytes, message: str) -> None:
    with pytest.raises(MTPError, match=message):
        decode_body(content_type, body)


@pytest.fixture
def server() -> Iterator[tuple[str, queue.SimpleQueue[MTPMessage], Counter[str]]]:
    got: queue.SimpleQueue[MTPMessage] = queue.SimpleQueue()
    counts: Counter[str] = Counter()
    port = free_port()

    def deliver(message: MTPMessage, peer: str) -> None:
        if message.payload == b"refuse me":
            raise MTPError("no ACL message")
        got.put(message)

    srv = MTPServer(("127.0.0.1", port), deliver, lambda name: counts.update([name]))
    srv.start()
    try:
        yield f"http://127.0.0.1:{port}/acc", got, counts
    finally:
        srv.stop()


def test_the_server_answers_as_jade_does_and_keeps_running(
    server: tuple[str, queue.SimpleQueue[MTPMessage], Counter[str]],
) -> None:
    url, got, counts = server
    good = jade_body(envelope_xml("a_hi", JADE, "http://h:1/acc", len(ACL)), ACL)
    assert post(url, b"garbage", "text/plain") == 406
    assert post(url, jade_body(envelope_xml("a_hi", JADE, "", 9), b"refuse me")) == 406
    assert post(url, good) == 200
    assert got.get(timeout=5).payload == ACL
    assert counts["http.406"] == 2 and counts["http.200"] == 1


def test_post_message_reaches_a_jade_platform() -> None:
    platform = JadePlatform()
    try:
        payload = b'(inform :sender (agent-identifier :name a_hi) :content "done")'
        env = Envelope(
            to=(AgentIdentifier(JADE),), from_=AgentIdentifier("a_hi"), payload_encoding="US-ASCII"
        )
        post_message(platform.address, MTPMessage(env, payload))
        received = platform.next()
        assert received.msg.content == b"done" and received.envelope.find(".//payload-length") is not None
        with pytest.raises(MTPError, match="only http"):
            post_message("https://h:1/acc", MTPMessage(env, payload))
    finally:
        platform.close()


def test_the_body_reader_takes_bare_line_feeds_and_transfer_encodings() -> None:
    xml = envelope_xml("a_hi", JADE, "http://h:1/acc", len(ACL)).encode()
    b = BOUNDARY.encode()
    lf = b"preamble\n--" + b + b"\n\n" + xml + b"\n--" + b + b"\n\n" + ACL + b"\n--" + b + b"--\n"
    assert decode_body(f"multipart/mixed; boundary={BOUNDARY}", lf).payload == ACL
    encoded = jade_body(envelope_xml("a_hi", JADE, "", 1), b"").replace(
        b"charset=US-ASCII\r\n\r\n\r\n",
        b"charset=US-ASCII\r\nContent-Transfer-Encoding: base64\r\n\r\n" + base64.b64encode(ACL) + b"\r\n",
    )
    assert decode_body(f'multipart/mixed; boundary="{BOUNDARY}"', encoded).payload == ACL


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (jade_body("<envelope>" + " " * 70_000 + "</envelope>", ACL), "at most 65536"),
        (
            jade_body(envelope_xml("a_hi", JADE, "", 1), ACL).replace(
                b"Content-Type: application/xml\r\n",
                b"Content-Type: application/xml\r\nX-a: " + b"b" * 9000 + b"\r\n",
            ),
            "part 1: no blank line after its headers within 8192 octets",
        ),
        (b"--" + BOUNDARY.encode() + b"\r\n\r\n<envelope/>", "part 1 has no boundary line after it"),
        (
            jade_body(envelope_xml("a_hi", JADE, "", 1), ACL).replace(
                b"charset=US-ASCII\r\n", b"charset=US-ASCII\r\nContent-Transfer-Encoding: x-uuencode\r\n"
            ),
            "Content-Transfer-Encoding 'x-uuencode' is not read here",
        ),
    ],
)
def test_the_body_reader_refuses_over_its_limits(body: bytes, message: str) -> None:
    with pytest.raises(MTPError, match=message):
        decode_body(f'multipart/mixed; boundary="{BOUNDARY}"', body)
