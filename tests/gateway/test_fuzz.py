"""Hypothesis over what a peer controls: the body reader (FIPA SC00084 multipart), the envelope
reader (SC00085 XML), the string form reader (SC00070) with its token limit, the gateway's
``deliver`` and the HTTP server itself. Each takes anything and either reads it or refuses it
with its own one-line error (an HTTP 4xx), never another exception, a 500 or a silent close."""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from services.bench.gateway import BOUNDARY, acl, envelope
from services.fleet.launcher import free_port
from services.gateway.bounds import Limits
from services.gateway.bridge import Gateway
from services.gateway.envelope import Envelope, EnvelopeError, parse_xml
from services.gateway.http_mtp import MTPError, MTPMessage, decode_body
from services.gateway.server import MTPServer, Refused
from services.runtime.memory_transport import MemoryBus
from services.spec.model import default_spec
from shared.fipa_codec import AgentIdentifier
from shared.fipa_codec.string_form import StringFormError, _Lexer, parse

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# ------------------------------------------------------------------------------- pieces
lines = st.sampled_from([b"\r\n", b"\n", b"", b" "])
transfer = st.sampled_from(
    [
        b"",
        b"Content-Transfer-Encoding: base64\r\n",
        b"Content-Transfer-Encoding: quoted-printable\r\n",
        b"Content-Transfer-Encoding: x-uuencode\r\n",
        b"Content-Transfer-Encoding: 8bit\r\n",
    ]
)
xml_fragments = st.sampled_from(
    [
        "<envelope>",
        "</envelope>",
        '<params index="1">',
        '<params index="99999999999999999">',
        "</params>",
        "<to><agent-identifier><name>a_hi</name></agent-identifier></to>",
        "<from><agent-identifier><name>da0@h</name><addresses><url>http://h:1/acc</url></addresses>",
        "</agent-identifier></from>",
        "<acl-representation>fipa.acl.rep.string.std</acl-representation>",
        "<payload-length>12</payload-length>",
        "<payload-length>" + "9" * 40 + "</payload-length>",
        "<payload-encoding>UTF-8</payload-encoding>",
        '<!DOCTYPE envelope [<!ENTITY a "b">]>',
        "&a;",
        "<![CDATA[x]]>",
        "<?xml version='1.0'?>",
        "<a>",
        "</a>",
        "&amp;",
        "\u2028",
        "\x00",
    ]
)
acl_fragments = st.sampled_from(
    [
        "(",
        ")",
        "request",
        "REQUEST",
        ":sender",
        ":receiver",
        "(agent-identifier :name da0@host:1099/JADE",
        ":addresses (sequence http://h:1/acc",
        "(set",
        ":content",
        '"hello"',
        '"a \\" b"',
        '#5"abcde',
        '#99999999999999"',
        ":language L_HC",
        ":protocol fipa-request",
        ":reply-by 20261121T153000000Z",
        ":X-a",
        "+1",
        "9x",
        " ",
        "\n",
        "\\",
        '"',
    ]
)


@st.composite
def multipart(draw: st.DrawFn) -> tuple[str, bytes]:
    boundary = draw(st.sampled_from([BOUNDARY, "b", "x" * 70, ""]))
    ctype = draw(
        st.sampled_from(
            [
                f'multipart/mixed ; boundary="{boundary}"',
                f"multipart/mixed; boundary={boundary}",
                "multipart/mixed",
                "text/plain",
                f"MULTIPART/MIXED;BOUNDARY={boundary};x=y",
            ]
        )
    )
    out = [draw(st.binary(max_size=20)), draw(lines)]
    for _ in range(draw(st.integers(0, 3))):
        out += [
            b"--" + boundary.encode(),
            draw(lines),
            draw(transfer),
            draw(st.binary(max_size=30)),
            draw(lines),
        ]
        out += [draw(lines), draw(st.binary(max_size=60)), draw(lines)]
    if draw(st.booleans()):
        out += [b"--" + boundary.encode() + b"--", draw(lines)]
    return ctype, b"".join(out)


# ------------------------------------------------------------------------------- readers
@FUZZ
@given(st.one_of(multipart(), st.tuples(st.text(max_size=40), st.binary(max_size=200))))
def test_the_body_reader_reads_or_refuses_anything(case: tuple[str, bytes]) -> None:
    content_type, body = case
    try:
        decode_body(content_type, body, Limits(max_part_headers=64, max_envelope=512))
    except MTPError as exc:
        assert "\n" not in str(exc)


@FUZZ
@given(
    st.one_of(
        st.lists(xml_fragments, max_size=25).map("".join), st.text(max_size=100), st.binary(max_size=100)
    )
)
def test_the_envelope_reader_reads_or_refuses_anything(xml: str | bytes) -> None:
    try:
        env = parse_xml(xml, max_size=4096, max_digits=12)
    except EnvelopeError as exc:
        assert "\n" not in str(exc) or "not XML" in str(exc)
    else:
        assert env.to and (env.payload_length is None or env.payload_length < 10**12)


@FUZZ
@given(st.lists(acl_fragments, max_size=40).map(" ".join), st.integers(1, 30))
def test_the_string_form_reader_stops_at_its_token_limit(text: str, limit: int) -> None:
    tokens = 0
    lexer = _Lexer(text, False, 10**6)
    try:
        while lexer.take() is not None:
            tokens += 1
    except StringFormError:
        tokens = -1  # a token that does not read: the limited reader stops there or before
    try:
        limited = parse(text, max_tokens=limit)
    except StringFormError as exc:
        if "tokens" in exc.reason:
            assert tokens == -1 or tokens > limit
        else:
            with pytest.raises(StringFormError):
                parse(text)
    else:
        assert 0 < tokens <= limit and parse(text) == limited


@pytest.fixture(scope="module")
def gateway() -> Iterator[Gateway]:
    async def nowhere(address: str, message: MTPMessage) -> None:
        raise OSError("not posted in this test")

    g = Gateway(MemoryBus().transport(), default_spec(), "http://127.0.0.1:1/acc", post=nowhere)
    g.start()
    try:
        yield g
    finally:
        g.stop()


@FUZZ
@given(
    st.lists(acl_fragments, max_size=40).map(" ".join),
    st.sampled_from([None, "US-ASCII", "UTF-8", "ISO-8859-1", "UTF-16", "utf-7", "punycode"]),
)
def test_deliver_takes_or_refuses_any_payload(gateway: Gateway, text: str, encoding: str | None) -> None:
    envelope_ = Envelope(to=(AgentIdentifier("a_hi"),), payload_encoding=encoding)
    with contextlib.suppress(MTPError, Refused):  # anything else fails the test
        gateway.deliver(MTPMessage(envelope_, text.encode("utf-8", "replace")), "10.0.0.1")


# ------------------------------------------------------------------------------- the server
@pytest.fixture(scope="module")
def server() -> Iterator[tuple[str, int]]:
    def deliver(message: MTPMessage, peer: str) -> None:
        if b"forbidden" in message.payload:
            raise Refused(403, "no")

    port = free_port()
    srv = MTPServer(
        ("127.0.0.1", port), deliver, lambda name: None, limits=Limits(header_s=5.0, request_s=5.0)
    )
    srv.start()
    try:
        yield ("127.0.0.1", port)
    finally:
        srv.stop()


token = st.text(alphabet=st.characters(min_codepoint=0x21, max_codepoint=0x7E), min_size=1, max_size=12)


@st.composite
def requests(draw: st.DrawFn) -> bytes:
    method = draw(st.sampled_from([b"POST", b"GET", b"PUT", b"FOO", b"post"]))
    target = draw(st.sampled_from([b"/acc", b"http://h:1/acc", b"*", b"/" + b"a" * 9000]))
    body = draw(
        st.one_of(
            st.binary(max_size=200),
            st.builds(
                lambda x, p: (
                    b"--"
                    + BOUNDARY.encode()
                    + b"\r\n\r\n"
                    + x.encode()
                    + b"\r\n--"
                    + BOUNDARY.encode()
                    + b"\r\n\r\n"
                    + p.encode()
                    + b"\r\n--"
                    + BOUNDARY.encode()
                    + b"--"
                ),
                st.sampled_from([envelope("a_hi", "da0@h", 3), "<envelope/>", "x"]),
                st.sampled_from([acl("da0@h", "a_hi", "x", "c"), "forbidden", "(x"]),
            ),
        )
    )
    headers = draw(st.lists(st.tuples(token, token), max_size=5))
    length = draw(st.sampled_from([str(len(body)).encode(), b"9" * 30, b"-1", b"", None]))
    head = [method + b" " + target + b" HTTP/1.1", b"Host: h"]
    head += [
        f"{k}: {v}".encode() for k, v in headers if k.lower() not in ("content-length", "transfer-encoding")
    ]
    head.append(f'Content-Type: multipart/mixed; boundary="{BOUNDARY}"'.encode())
    if length is not None:
        head.append(b"Content-Length: " + length)
    return b"\r\n".join(head) + b"\r\n\r\n" + body


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(requests())
def test_the_server_answers_any_request_with_one_status(server: tuple[str, int], data: bytes) -> None:
    with socket.create_connection(server, timeout=30) as s:
        s.sendall(data)
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    status = int(answer.split(b" ", 2)[1])
    assert status in (200, 400, 403, 405, 406, 411, 413, 431), answer[:300]
    assert answer.count(b"<h1>") == 1
