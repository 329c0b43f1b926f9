"""The FIPA agent message transport over HTTP (FIPA SC00084), as JADE's HTTP MTP speaks it:
the body, a server that takes messages, a client that posts them. Standard library only.

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

(line ends CRLF; the request target is the whole address, as JADE writes it; a server also
takes a plain path). The receiver answers ``200 OK`` when it has taken the message for
delivery and ``406 Not Acceptable`` when it cannot read it (JADE answers these two; roco's
server also answers ``413`` to a body over :data:`MAX_BODY`, ``411`` without a
Content-Length and ``405`` to any method but POST). The answer to the message itself, if any,
is another POST, to the address the message names (not this HTTP response).

Not supported: HTTPS (JADE's ``https://`` addresses), keep-alive connections (every message
is one connection: ``Connection: close``), chunked bodies, IIOP (FIPA SC00075).
"""

from __future__ import annotations

import http.client
import logging
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from email.message import Message
from email.parser import BytesParser
from email.policy import compat32
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import urlsplit

from services.gateway.envelope import Envelope, EnvelopeError, parse_xml, to_xml

__all__ = [
    "MAX_BODY",
    "PREAMBLE",
    "MTPError",
    "MTPMessage",
    "MTPServer",
    "decode_body",
    "encode_body",
    "post_message",
]

MAX_BODY = 8 * 1024 * 1024
"""Largest body (octets) the server reads; a larger one is answered 413 and not read."""
PREAMBLE = b"This is not part of the MIME multipart encoded message."
"""The line before the first boundary, as JADE writes it (MIME ignores it)."""

log = logging.getLogger("gateway")


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


def decode_body(content_type: str, body: bytes) -> MTPMessage:
    """Read a POST's body (module docstring): the first part is the XML envelope, the second
    the payload. Raises MTPError when the content type is not ``multipart/mixed`` with a
    boundary, there are fewer than two parts, or the envelope does not read (EnvelopeError's
    reason)."""
    if not content_type.strip().lower().startswith("multipart/mixed"):
        raise MTPError(f"the body is {content_type.split(';')[0].strip() or 'untyped'}, not multipart/mixed")
    head = b"Content-Type: " + content_type.encode("latin-1", "replace") + b"\r\nMIME-Version: 1.0\r\n\r\n"
    parsed = BytesParser(policy=compat32).parsebytes(head + body)
    if parsed.get_boundary() is None:
        raise MTPError("multipart/mixed without a boundary")
    parts = parsed.get_payload() if parsed.is_multipart() else []
    if not isinstance(parts, list) or len(parts) < 2:
        raise MTPError(
            f"expected 2 parts (envelope, payload), found {len(parts) if isinstance(parts, list) else 0}"
        )
    first, second = parts[0], parts[1]
    if not isinstance(first, Message) or not isinstance(second, Message):
        raise MTPError("the parts of the body do not read")
    xml = first.get_payload(decode=True)
    payload = second.get_payload(decode=True)
    if not isinstance(xml, bytes) or not isinstance(payload, bytes):
        raise MTPError("a part of the body is itself multipart")
    try:
        envelope = parse_xml(xml)
    except EnvelopeError as exc:
        raise MTPError(str(exc)) from None
    return MTPMessage(envelope, payload)


def post_message(address: str, message: MTPMessage, timeout: float = 10.0) -> None:
    """POST ``message`` to ``address`` (an ``http://host:port/path`` URL) as JADE does (module
    docstring). Raises MTPError when the address is not an http URL or the receiver answers
    anything but 200, OSError when it cannot be reached."""
    url = urlsplit(address)
    if url.scheme.lower() != "http" or not url.hostname:
        raise MTPError(f"cannot post to {address!r}: only http://host:port/… addresses (no https)")
    content_type, body = encode_body(message)
    connection = http.client.HTTPConnection(url.hostname, url.port or 80, timeout=timeout)
    try:
        connection.putrequest("POST", address, skip_host=True, skip_accept_encoding=True)
        for name, value in (
            ("Cache-Control", "no-cache"),
            ("Mime-Version", "1.0"),
            ("Host", f"{url.hostname}:{url.port or 80}"),
            ("Content-Type", content_type),
            ("Content-Length", str(len(body))),
            ("Connection", "close"),
        ):
            connection.putheader(name, value)
        connection.endheaders(body)
        response = connection.getresponse()
        response.read()
    finally:
        connection.close()
    if response.status != 200:
        raise MTPError(f"{address} answered {response.status} {response.reason}")


Deliver = Callable[[MTPMessage], None]
"""What the server calls with each message it read; raising MTPError answers 406 with its
reason (e.g. a payload that is no ACL message), anything else 500."""


class _Handler(BaseHTTPRequestHandler):
    server: MTPServer
    protocol_version = "HTTP/1.1"
    timeout = 30.0
    """Seconds a connection may stay silent (a client that never sends its body is dropped)."""

    def log_message(self, format: str, *args: object) -> None:
        log.debug("%s " + format, self.client_address[0], *args)

    def _answer(self, code: int, reason: str) -> None:
        """Answer as JADE does: a one-line HTML page naming the status; close the connection."""
        text = f"{code} {reason}"
        page = f"<html><body><h1>{text}</h1></body></html>".encode()
        self.send_response(code, reason)
        self.send_header("Content-Type", "text/html")
        self.send_header("Cache-Control", "no-cache")
        self.send_header("Content-Length", str(len(page)))
        self.send_header("Connection", "close")
        self.end_headers()
        self.wfile.write(page)
        self.close_connection = True

    def _refuse(self, code: int, reason: str, why: str) -> None:
        self.server.count(f"http.{code}")
        log.warning("HTTP %d to %s: %s", code, self.client_address[0], why)
        self._answer(code, reason)

    def do_POST(self) -> None:
        length = self.headers.get("Content-Length")
        if length is None or not length.strip().isdigit():
            self._refuse(411, "Length Required", "no Content-Length (chunked bodies are not read)")
            return
        size = int(length)
        if size > MAX_BODY:
            self._refuse(413, "Payload Too Large", f"a body of {size} octets (at most {MAX_BODY})")
            return
        body = self.rfile.read(size)
        try:
            message = decode_body(self.headers.get("Content-Type", ""), body)
            self.server.deliver(message)
        except MTPError as exc:
            self._refuse(406, "Not Acceptable", str(exc))
            return
        except Exception as exc:  # the server keeps running whatever one message does
            log.exception("delivering a message raised")
            self._refuse(500, "Internal Server Error", f"{type(exc).__name__}: {exc}")
            return
        self.server.count("http.200")
        self._answer(200, "OK")

    def _not_post(self) -> None:
        self._refuse(405, "Method Not Allowed", f"{self.command} instead of POST")

    do_GET = do_PUT = do_DELETE = do_HEAD = _not_post


class MTPServer(ThreadingHTTPServer):
    """An HTTP server of the message transport (module docstring), one thread per connection:
    each message read is given to ``deliver``; ``count`` is called with ``http.<status>`` for
    every answer. Raises OSError when ``address`` (host, port) cannot be bound."""

    daemon_threads = True

    def __init__(self, address: tuple[str, int], deliver: Deliver, count: Callable[[str], None]) -> None:
        super().__init__(address, _Handler)
        self.deliver = deliver
        self.count = count
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Serve on a thread of its own until :meth:`stop`."""
        self._thread = threading.Thread(target=self.serve_forever, name="gateway-http", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self.shutdown()
        self.server_close()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
