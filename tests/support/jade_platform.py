"""A stand-in for a JADE platform's HTTP message transport (FIPA SC00084), written for the tests
with the standard library only and independently of services/gateway/: it posts messages laid out
as JADE 4.6's ``HTTPIO``/``XMLCodec`` write them (preamble line, quoted boundary, an XML envelope
part, an ACL string part, absolute request target) and receives the answers on an HTTP server of
its own, reading them as JADE's ``HTTPIO.readAll`` does (boundary from the quoted header value,
first part the envelope, second part the payload up to CRLF and the closing boundary)."""

from __future__ import annotations

import http.client
import queue
import re
import threading
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from services.fleet.launcher import free_port
from shared.fipa_codec import Communicate
from shared.fipa_codec.string_form import parse

JADE = "da0@host:1099/JADE"
"""The foreign agent's name, JADE's default form."""
BOUNDARY = "a36869921a26b9d812878b42b8fc2cd"


def envelope_xml(to: str, sender: str, sender_address: str, payload_length: int) -> str:
    """An XML envelope (FIPA SC00085) as JADE's ``XMLCodec.encodeXML`` writes it: no white space
    between tags, a UTC date."""

    def aid(name: str, address: str | None = None) -> str:
        urls = f"<url>{address}</url>" if address else ""
        return f"<agent-identifier><name>{name}</name><addresses>{urls}</addresses></agent-identifier>"

    return (
        '<?xml version="1.0"?>\n<envelope><params index="1">'
        f"<to>{aid(to)}</to><from>{aid(sender, sender_address)}</from>"
        "<acl-representation>fipa.acl.rep.string.std</acl-representation>"
        f"<payload-length>{payload_length}</payload-length>"
        "<payload-encoding>US-ASCII</payload-encoding><date>20261122T201900000Z</date>"
        f"<intended-receiver>{aid(to)}</intended-receiver></params></envelope>"
    )


def jade_body(xml: str, payload: bytes) -> bytes:
    """The multipart body JADE's ``HTTPIO.createHTTPBody`` writes."""
    b = BOUNDARY.encode()
    return b"".join(
        [
            b"This is not part of the MIME multipart encoded message.\r\n",
            b"--" + b + b"\r\nContent-Type: application/xml\r\n\r\n",
            xml.encode() + b"\r\n",
            b"--" + b + b"\r\nContent-Type: fipa.acl.rep.string.std; charset=US-ASCII\r\n\r\n",
            payload + b"\r\n",
            b"--" + b + b"--\r\n",
        ]
    )


def post(url: str, body: bytes, content_type: str | None = None) -> int:
    """POST ``body`` to ``url`` with JADE's headers (the whole URL as request target); the status."""
    m = re.match(r"http://([^:/]+):(\d+)", url)
    assert m, url
    connection = http.client.HTTPConnection(m.group(1), int(m.group(2)), timeout=10)
    try:
        connection.putrequest("POST", url, skip_host=True, skip_accept_encoding=True)
        connection.putheader("Cache-Control", "no-cache")
        connection.putheader("Mime-Version", "1.0")
        connection.putheader("Host", f"{m.group(1)}:{m.group(2)}")
        connection.putheader("Content-Type", content_type or f'multipart/mixed ; boundary="{BOUNDARY}"')
        connection.putheader("Content-Length", str(len(body)))
        connection.putheader("Connection", "close")
        connection.endheaders(body)
        response = connection.getresponse()
        response.read()
        return response.status
    finally:
        connection.close()


@dataclass(frozen=True)
class Received:
    """A message the platform received: the envelope's XML root and the ACL message."""

    envelope: ET.Element
    msg: Communicate


class JadePlatform:
    """Sends requests as ``da0@host:1099/JADE`` and collects the answers posted to its
    address (:attr:`address`)."""

    def __init__(self) -> None:
        self.inbox: queue.SimpleQueue[Received] = queue.SimpleQueue()
        platform = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def log_message(self, format: str, *args: object) -> None:
                pass

            def do_POST(self) -> None:
                body = self.rfile.read(int(self.headers["Content-Length"]))
                code = platform._take(self.headers.get("Content-Type", ""), body)
                page = f"<html><body><h1>{code}</h1></body></html>".encode()
                self.send_response(int(code.split()[0]))
                self.send_header("Content-Type", "text/html")
                self.send_header("Content-Length", str(len(page)))
                self.send_header("Connection", "close")
                self.end_headers()
                self.wfile.write(page)

        port = free_port()
        self.address = f"http://127.0.0.1:{port}/acc"
        self.server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
        self.server.daemon_threads = True
        self.thread = threading.Thread(target=self.server.serve_forever, args=(0.05,), daemon=True)
        self.thread.start()

    def _take(self, content_type: str, body: bytes) -> str:
        """Read a message as JADE does; ``200 OK`` or ``406 Not Acceptable``."""
        m = re.search(r'boundary\s*=\s*"([^"]+)"', content_type)
        if not content_type.lower().startswith("multipart/mixed") or m is None:
            return "406 Not Acceptable"
        delimiter = b"--" + m.group(1).encode()
        pieces = body.split(delimiter)
        if len(pieces) < 4 or not pieces[3].startswith(b"--"):
            return "406 Not Acceptable"
        parts = []
        for piece in pieces[1:3]:
            _headers, _, data = piece.partition(b"\r\n\r\n")
            parts.append(data[:-2] if data.endswith(b"\r\n") else data)
        self.inbox.put(Received(ET.fromstring(parts[0]), parse(parts[1])))
        return "200 OK"

    def request(self, gateway: str, to: str, acl: str) -> int:
        """Post the ACL message ``acl`` (string form) for agent ``to`` from :data:`JADE`."""
        payload = acl.encode()
        return post(gateway, jade_body(envelope_xml(to, JADE, self.address, len(payload)), payload))

    def acl(self, to: str, content: str, conversation: str, *, performative: str = "REQUEST") -> str:
        """A request as JADE's ``ACLMessage.toString`` prints it (upper-case performative, a
        space inside parentheses, the content as a quoted string)."""
        quoted = content.replace('"', '\\"')
        return (
            f"({performative}\n"
            f" :sender  ( agent-identifier :name {JADE}  :addresses (sequence {self.address} ))\n"
            f" :receiver  (set ( agent-identifier :name {to} ) )\n"
            f' :content  "{quoted}" \n'
            " :language  L_HC  :ontology  O_RoCo  :protocol  fipa-request\n"
            f" :conversation-id  {conversation}\n :reply-with  {conversation}-r1 )"
        )

    def next(self, timeout: float = 10.0) -> Received:
        """The next message received."""
        return self.inbox.get(timeout=timeout)

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()
