"""The FIPA agent message transport over HTTP (FIPA SC00084), as JADE's HTTP MTP speaks it:
the body (written and read) and a client that posts it (aiohttp). The server that takes
messages is services/gateway/server.py.

A message is one ``POST`` whose body is ``multipart/mixed`` (SC00084 §2; JADE 4.6's
``jade.mtp.http.HTTPIO``)::

    POST http://host:7778/acc HTTP/1.1
    Cache-Control: no-cache
    Mime-Version: 1.0
    Host: host:7778
    Content-Type: multipart/mixed ; boundary="a36869921a26b9d812878b42b8fc2cd"
    Content-Length: 1097
    Connection: close

    This is not part of the MIME multipart encoded message.
    --a36869921a26b9d812878b42b8fc2cd
    Content-Type: application/xml

    <?xml version="1.0"?>
    <envelope>…</envelope>                    the envelope (FIPA SC00085: services/gateway/envelope.py)
    --a36869921a26b9d812878b42b8fc2cd
    Content-Type: fipa.acl.rep.string.std; charset=US-ASCII

    (request :sender …)                       the payload (FIPA SC00070 string form)
    --a36869921a26b9d812878b42b8fc2cd--

(line ends CRLF). The receiver answers ``200 OK`` when it has taken the message for delivery
and ``406 Not Acceptable`` when it cannot read it (JADE answers these two; roco's server,
services/gateway/server.py, also answers other HTTP statuses for what is over its limits). The
answer to the message itself, if any, is another POST, to the address the message names (not
this HTTP response).

Reading (:func:`decode_body`) splits the body at its boundary lines with linear searches
(RFC 2046 §5.1.1: CRLF or a bare LF before each boundary line; text before the first is the
preamble), reads each part's header block (at most ``max_part_headers`` octets) and undoes its
``Content-Transfer-Encoding`` (7bit, 8bit, binary, base64, quoted-printable; any other is
refused). Only the first two parts are read; the envelope part is refused over
``max_envelope`` octets before it is parsed.

Posting (:func:`post`): an aiohttp client request with JADE's headers; the request target is
the address's path (RFC 9112 §3.2.1 origin form; JADE writes the whole URL, and its server,
``HTTPIO.readAll``, as roco's, reads past it); redirects are not followed; only the status
line and headers of the answer are read.

Not supported: HTTPS (JADE's ``https://`` addresses), keep-alive connections (every message
is one connection: ``Connection: close``), chunked bodies, IIOP (FIPA SC00075).
"""

from __future__ import annotations

import asyncio
import base64
import binascii
import os
import re
from dataclasses import dataclass, replace
from urllib.parse import urlsplit

import aiohttp

from services.gateway.bounds import DEFAULT_LIMITS, Limits
from services.gateway.envelope import Envelope, EnvelopeError, parse_xml, to_xml

__all__ = [
    "HEADERS",
    "PREAMBLE",
    "MTPError",
    "MTPMessage",
    "check_address",
    "client_session",
    "decode_body",
    "encode_body",
    "post",
    "post_message",
]

PREAMBLE = b"This is not part of the MIME multipart encoded message."
"""The line before the first boundary, as JADE writes it (MIME ignores it)."""
HEADERS = {"Cache-Control": "no-cache", "Mime-Version": "1.0", "Connection": "close"}
"""The headers JADE's ``HTTPIO`` writes besides Host, Content-Type and Content-Length."""


class MTPError(ValueError):
    """A body that is not a FIPA SC00084 message (answered ``406 Not Acceptable``), or a POST
    that the receiving platform did not accept (the status in the message); one line."""


@dataclass(frozen=True)
class MTPMessage:
    """One message of the transport: its ``envelope`` (FIPA SC00085) and its ``payload``, the
    octets of the ACL message in the envelope's representation."""

    envelope: Envelope
    payload: bytes


def encode_body(message: MTPMessage, boundary: str | None = None) -> tuple[str, bytes]:
    """The ``Content-Type`` header value and body of a POST carrying ``message`` (module
    docstring), with ``payload-length`` set to the payload's length. ``boundary`` (default: 32
    random hex digits) must not occur in the parts."""
    boundary = boundary or os.urandom(16).hex()
    envelope = replace(message.envelope, payload_length=len(message.payload))
    charset = envelope.payload_encoding
    kind = f"{envelope.acl_representation}; charset={charset}" if charset else "application/text"
    b = boundary.encode("ascii")
    body = b"".join(
        [
            PREAMBLE + b"\r\n",
            b"--" + b + b"\r\n",
            b"Content-Type: application/xml\r\n\r\n",
            to_xml(envelope) + b"\r\n",
            b"--" + b + b"\r\n",
            b"Content-Type: " + kind.encode("ascii") + b"\r\n\r\n",
            message.payload + b"\r\n",
            b"--" + b + b"--\r\n",
        ]
    )
    return f'multipart/mixed ; boundary="{boundary}"', body


_BOUNDARY = re.compile(r';\s*boundary\s*=\s*(?:"([^"\r\n]{1,200})"|([^;\s"]{1,200}))', re.IGNORECASE)


def _boundary(content_type: str) -> bytes:
    """The boundary of a ``multipart/mixed`` content type; MTPError when it is not one."""
    kind = content_type.split(";", 1)[0].strip()
    if kind.lower() != "multipart/mixed":
        raise MTPError(f"the body is {kind[:60]!r}, not multipart/mixed" if kind else "the body is untyped")
    m = _BOUNDARY.search(content_type)
    if m is None:
        raise MTPError("multipart/mixed without a boundary (1 to 200 characters)")
    return (m.group(1) or m.group(2)).encode("latin-1", "replace")


def _parts(body: bytes, boundary: bytes, wanted: int) -> list[bytes]:
    """The first ``wanted`` parts of a multipart ``body`` (module docstring), each its header
    block and content as they stand; fewer when the closing boundary comes first."""
    delimiter = b"--" + boundary
    if body.startswith(delimiter):
        at = 0
    else:
        at = body.find(b"\n" + delimiter)
        if at < 0:
            raise MTPError("the body holds no boundary line")
        at += 1
    parts: list[bytes] = []
    while len(parts) < wanted:
        after = at + len(delimiter)
        if body.startswith(b"--", after):
            break  # the closing boundary
        line_end = body.find(b"\n", after)
        if line_end < 0:
            raise MTPError(f"the boundary line before part {len(parts) + 1} does not end")
        start = line_end + 1
        following = body.find(b"\n" + delimiter, line_end)
        if following < 0:
            raise MTPError(f"part {len(parts) + 1} has no boundary line after it")
        end = following - 1 if following > start and body[following - 1] == 0x0D else following
        parts.append(body[start : max(start, end)])
        at = following + 1
    return parts


def _split_part(part: bytes, number: int, limits: Limits) -> tuple[bytes, bytes]:
    """One MIME part's header block and content; MTPError when the block is over the limit or
    does not end."""
    if part.startswith(b"\r\n") or part.startswith(b"\n"):
        return b"", part[2 if part.startswith(b"\r\n") else 1 :]
    window = limits.max_part_headers + 4
    found = [
        (i, n)
        for i, n in ((part.find(b"\r\n\r\n", 0, window), 4), (part.find(b"\n\n", 0, window), 2))
        if i >= 0
    ]
    if not found:
        raise MTPError(
            f"part {number}: no blank line after its headers within {limits.max_part_headers} octets"
        )
    i, n = min(found)
    return part[:i], part[i + n :]


def _transfer_encoding(head: bytes) -> str:
    """The (last) Content-Transfer-Encoding of a part's header block, lower case ("": none)."""
    encoding = ""
    for line in re.split(rb"\r?\n(?![ \t])", head):
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"content-transfer-encoding":
            encoding = value.decode("latin-1").strip().lower()
    return encoding


def _content(part: bytes, number: int, limits: Limits) -> bytes:
    """The content of one MIME part, its transfer encoding undone; MTPError when its header
    block is over the limit or does not end, or the transfer encoding is unknown or broken."""
    head, content = _split_part(part, number, limits)
    encoding = _transfer_encoding(head)
    if encoding in ("", "7bit", "8bit", "binary"):
        return content
    try:
        if encoding == "base64":
            return base64.b64decode(content)
        if encoding == "quoted-printable":
            return binascii.a2b_qp(content)
    except (binascii.Error, ValueError) as exc:
        raise MTPError(f"part {number}: not {encoding}: {exc}") from None
    raise MTPError(f"part {number}: Content-Transfer-Encoding {encoding[:40]!r} is not read here")


def decode_body(content_type: str, body: bytes, limits: Limits = DEFAULT_LIMITS) -> MTPMessage:
    """Read a POST's body (module docstring): the first part is the XML envelope, the second
    the payload. Linear in ``len(body)``. Raises MTPError when the content type is not
    ``multipart/mixed`` with a boundary, there are fewer than two parts, a part is malformed
    (its header block, its transfer encoding), the envelope is over ``limits.max_envelope``
    octets, or it does not read (EnvelopeError's reason)."""
    parts = _parts(body, _boundary(content_type), 2)
    if len(parts) < 2:
        raise MTPError(f"expected 2 parts (envelope, payload), found {len(parts)}")
    xml = _content(parts[0], 1, limits)
    payload = _content(parts[1], 2, limits)
    try:
        envelope = parse_xml(xml, max_size=limits.max_envelope, max_digits=limits.max_digits)
    except EnvelopeError as exc:
        raise MTPError(str(exc)) from None
    return MTPMessage(envelope, payload)


def check_address(address: str) -> None:
    """Raise MTPError when ``address`` is not an ``http://host[:port]/…`` URL (no https)."""
    try:
        url = urlsplit(address)
        url.port  # noqa: B018 (raises ValueError for a port that is no number or out of range)
    except ValueError:
        raise MTPError(f"cannot post to {address[:80]!r}: not a URL") from None
    if url.scheme.lower() != "http" or not url.hostname:
        raise MTPError(f"cannot post to {address[:80]!r}: only http://host:port/… addresses (no https)")


async def post(session: aiohttp.ClientSession, address: str, message: MTPMessage) -> None:
    """POST ``message`` to ``address`` with ``session`` (its timeouts and pool apply) as JADE
    does (module docstring). Raises MTPError when the address is not an http URL or the
    receiver answers anything but 200; aiohttp.ClientError, OSError or TimeoutError when it
    cannot be reached or does not answer in time."""
    check_address(address)
    content_type, body = encode_body(message)
    headers = {**HEADERS, "Content-Type": content_type}
    async with session.post(address, data=body, headers=headers, allow_redirects=False) as response:
        status, reason = response.status, (response.reason or "")[:80]
    if status != 200:
        raise MTPError(f"{address[:120]} answered {status} {reason}")


def client_session(
    limits: Limits = DEFAULT_LIMITS, connector: aiohttp.BaseConnector | None = None
) -> aiohttp.ClientSession:
    """An aiohttp client for :func:`post` (call it on the event loop that will use it): at
    most ``limits.max_posts`` connections, none kept alive, ``limits.post_connect_s`` to
    connect and ``limits.post_s`` for a whole post; no User-Agent or Accept headers (they would
    name versions), no proxy from the environment."""
    return aiohttp.ClientSession(
        connector=connector or aiohttp.TCPConnector(limit=limits.max_posts, force_close=True),
        timeout=aiohttp.ClientTimeout(total=limits.post_s, sock_connect=limits.post_connect_s),
        skip_auto_headers=("User-Agent", "Accept", "Accept-Encoding"),
        auto_decompress=False,
        trust_env=False,
    )


def post_message(address: str, message: MTPMessage, limits: Limits = DEFAULT_LIMITS) -> None:
    """:func:`post` once, on an event loop of its own (tools and tests; the gateway posts with
    services/gateway/poster.py). Raises as :func:`post`."""

    async def once() -> None:
        async with client_session(limits) as session:
            await post(session, address, message)

    asyncio.run(once())
