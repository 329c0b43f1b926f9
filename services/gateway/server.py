"""The HTTP server of the FIPA agent message transport (FIPA SC00084): aiohttp's low-level
server, kept within the gateway's limits (services/gateway/bounds.py).

One message is one POST on one connection (``Connection: close``, as JADE writes and expects
it). For each connection, in order:

- more than ``max_connections`` open at once: ``503`` and closed;
- the request line and headers must arrive within ``header_s`` of the accept (else ``408``
  and closed) and within aiohttp's parser limits (``max_line``, ``max_header``,
  ``max_headers``; else ``431``); anything that is no HTTP request is answered ``400``;
- a method other than POST: ``405``; no ``Content-Length`` or a chunked body: ``411``; a
  length that is no number of at most ``max_digits`` digits: ``400``; over ``max_body``:
  ``413``, the body not read;
- the body must arrive within ``request_s`` (else ``408``) and fit, with every other body being
  read or parsed, in ``max_buffered`` (else ``503``);
- a reader thread (``readers`` of them) splits the body and reads envelope and payload
  (services/gateway/http_mtp.py) and gives the message to ``deliver`` with the peer's IP
  address: ``200`` when it took it, ``406`` when it raised MTPError (not a message of the
  transport), the status of a :class:`Refused` it raised (``403`` a sender it will not take
  from this peer, ``503`` too many messages waiting).

Every answer is a one-line HTML page naming its status, as JADE writes it, with no version in
any header (``Server: roco``), and is counted ``http.<status>``; every refusal is also logged,
one WARNING line naming the peer and the reason.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from http import HTTPStatus
from typing import Any

from aiohttp import web
from aiohttp.http_exceptions import BadHttpMessage, LineTooLong
from aiohttp.web_protocol import RequestHandler

from services.gateway.bounds import DEFAULT_LIMITS, BoundError, Limits, read_digits
from services.gateway.http_mtp import MTPError, MTPMessage, decode_body
from services.gateway.loop_thread import LoopThread

__all__ = ["Deliver", "MTPServer", "Refused"]

log = logging.getLogger("gateway")


class Refused(Exception):
    """What ``deliver`` raises to answer a message with HTTP ``status`` (4xx, 5xx); ``why`` is
    logged, one line."""

    def __init__(self, status: int, why: str) -> None:
        super().__init__(why)
        self.status = status
        self.why = why


Deliver = Callable[[MTPMessage, str], None]
"""What the server calls (on a reader thread) with each message it read and the IP address of
the peer that sent it; raises MTPError (answered 406) or :class:`Refused`."""


def _page(status: int) -> bytes:
    text = f"{status} {HTTPStatus(status).phrase}"
    return f"<html><body><h1>{text}</h1></body></html>".encode()


def _raw_answer(status: int) -> bytes:
    """A whole HTTP answer, for a connection refused before aiohttp reads a request."""
    page = _page(status)
    head = (
        f"HTTP/1.1 {status} {HTTPStatus(status).phrase}\r\nServer: roco\r\nContent-Type: text/html\r\n"
        f"Cache-Control: no-cache\r\nContent-Length: {len(page)}\r\nConnection: close\r\n\r\n"
    )
    return head.encode("ascii") + page


def _refusal_status(status: int, exc: BaseException | None, why: str) -> int:
    """431 (RFC 6585) for a request line or header over the limits, or too many headers;
    ``status`` otherwise."""
    if isinstance(exc, LineTooLong) or (isinstance(exc, BadHttpMessage) and "Too many headers" in why):
        return 431
    return status


class _Protocol(RequestHandler):
    """aiohttp's connection handler, with the gateway's cap on connections, its deadline for
    the headers and its one-line answer to a request aiohttp cannot parse."""

    def __init__(self, manager: _Server, **kwargs: Any) -> None:
        super().__init__(manager, **kwargs)
        self.gate = manager.gate
        self.headers_read = False
        self._timer: asyncio.TimerHandle | None = None
        self._counted = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)
        gate = self.gate
        gate.connections += 1
        self._counted = True
        if gate.connections > gate.limits.max_connections:
            peer = transport.get_extra_info("peername")
            gate.refused(
                503, str(peer[0]) if peer else "?", f"over {gate.limits.max_connections} connections"
            )
            gate.count("http.503")
            self._close_with(transport, 503)
            return
        self._timer = asyncio.get_running_loop().call_later(gate.limits.header_s, self._headers_late)

    def _close_with(self, transport: asyncio.BaseTransport, status: int) -> None:
        if isinstance(transport, asyncio.WriteTransport) and not transport.is_closing():
            transport.write(_raw_answer(status))
        self.force_close()

    def _headers_late(self) -> None:
        self._timer = None
        if self.headers_read or self.transport is None:
            return
        peer = self.transport.get_extra_info("peername")
        self.gate.refused(
            408,
            str(peer[0]) if peer else "?",
            f"no whole request head within {self.gate.limits.header_s:g} s",
        )
        self.gate.count("http.408")
        self._close_with(self.transport, 408)

    def connection_lost(self, exc: BaseException | None) -> None:
        if self._counted:
            self._counted = False
            self.gate.connections -= 1
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        super().connection_lost(exc)

    def handle_error(
        self,
        request: web.BaseRequest,
        status: int = 500,
        exc: BaseException | None = None,
        message: str | None = None,
    ) -> web.StreamResponse:
        """What aiohttp itself refuses (400: no HTTP request, over the parser's limits), or an
        error of the handler: counted, logged in one line, answered with the one-line page."""
        if request.writer.output_size > 0:
            raise ConnectionError("an answer was sent already")
        why = (message or (str(exc) if exc else "") or HTTPStatus(status).phrase).split("\n", 1)[0]
        status = _refusal_status(status, exc, why)
        if status >= 500 and exc is not None:  # a fault of roco's, not of the peer: its traceback
            log.error("HTTP %d to %s: %s", status, request.remote or "?", why[:300], exc_info=exc)
        else:
            self.gate.refused(status, request.remote or "?", why)
        return self.gate.answer(status)


class _Server(web.Server):
    """aiohttp's low-level server making :class:`_Protocol` connection handlers."""

    def __init__(self, handler: Any, gate: MTPServer, *, handler_cancellation: bool, **kwargs: Any) -> None:
        super().__init__(handler, handler_cancellation=handler_cancellation, **kwargs)
        self.gate = gate
        self._kwargs_for_protocol = kwargs

    def __call__(self) -> RequestHandler:
        return _Protocol(self, loop=asyncio.get_running_loop(), **self._kwargs_for_protocol)


@dataclass
class _Received:
    """A request body as it is read: its declared size, its chunks and how many octets came
    (buffered until the request is answered)."""

    size: int
    chunks: list[bytes] = field(default_factory=list)
    got: int = 0


class MTPServer:
    """The HTTP server (module docstring) on ``address`` (host, port): each message read is
    given to ``deliver``; ``count`` is called with ``http.<status>`` for every answer (any
    thread). It runs on ``loop`` (a new one of its own when None) from :meth:`start` (which
    raises OSError when the address cannot be bound) until :meth:`stop`."""

    def __init__(
        self,
        address: tuple[str, int],
        deliver: Deliver,
        count: Callable[[str], None],
        *,
        limits: Limits = DEFAULT_LIMITS,
        loop: LoopThread | None = None,
    ) -> None:
        self.address = address
        self.deliver = deliver
        self.count = count
        self.limits = limits
        self._own_loop = loop is None
        self.loop = loop or LoopThread("gateway-http")
        self.connections = 0
        """Connections open now (the event loop's thread only)."""
        self._buffered = 0
        self._readers = ThreadPoolExecutor(limits.readers, thread_name_prefix="gateway-read")
        self._runner: web.ServerRunner | None = None

    # ---- life -----------------------------------------------------------------------------
    def start(self) -> None:
        """Bind and serve. Raises OSError when the address cannot be bound."""
        try:
            self.loop.run(self._start())
        except OSError:
            self._close()
            raise

    async def _start(self) -> None:
        limits = self.limits
        server = _Server(
            self._handle,
            self,
            handler_cancellation=True,
            keepalive_timeout=0,  # no keep-alive; the deadline of the head is _Protocol's
            max_line_size=limits.max_line,
            max_field_size=limits.max_header,
            max_headers=limits.max_headers,
            read_bufsize=16 * 1024,
            lingering_time=2.0,
            access_log=None,
        )
        runner = web.ServerRunner(server, handle_signals=False, shutdown_timeout=2.0)
        await runner.setup()
        site = web.TCPSite(runner, self.address[0], self.address[1], backlog=limits.backlog)
        try:
            await site.start()
        except BaseException:
            await runner.cleanup()
            raise
        self._runner = runner

    def stop(self) -> None:
        """Stop serving (connections open are closed) and free the port."""
        if self._runner is not None:
            runner, self._runner = self._runner, None
            with contextlib.suppress(TimeoutError, RuntimeError):  # the loop was stopped already
                self.loop.run(runner.cleanup())
        self._close()

    def _close(self) -> None:
        self._readers.shutdown(wait=False, cancel_futures=True)
        if self._own_loop:
            self.loop.stop()

    # ---- answers --------------------------------------------------------------------------
    def answer(self, status: int) -> web.Response:
        """The one-line page of ``status``, closing the connection; counted ``http.<status>``."""
        self.count(f"http.{status}")
        response = web.Response(
            status=status,
            body=_page(status),
            content_type="text/html",
            headers={"Server": "roco", "Cache-Control": "no-cache"},
        )
        response.force_close()
        return response

    def refused(self, status: int, peer: str, why: str) -> None:
        """Log a refusal, one line (why cut to 300 characters)."""
        log.warning("HTTP %d to %s: %s", status, peer, why[:300])

    def _refuse(self, status: int, peer: str, why: str) -> web.Response:
        self.refused(status, peer, why)
        return self.answer(status)

    # ---- one request ----------------------------------------------------------------------
    async def _handle(self, request: web.BaseRequest) -> web.StreamResponse:
        protocol = request.protocol
        if isinstance(protocol, _Protocol):
            protocol.headers_read = True
        peer = request.remote or "?"
        size = self._declared_size(request, peer)
        if not isinstance(size, int):
            return size
        received = _Received(size)
        try:
            refused = await self._receive(request, received, peer)
            if refused is not None:
                return refused
            body = b"".join(received.chunks)
            received.chunks.clear()
            content_type = request.headers.get("Content-Type", "")
            loop = asyncio.get_running_loop()
            try:
                await loop.run_in_executor(self._readers, self._read, content_type, body, peer)
            except MTPError as exc:
                return self._refuse(406, peer, str(exc))
            except Refused as exc:
                return self._refuse(exc.status, peer, exc.why)
        finally:
            self._buffered -= received.got
        return self.answer(200)

    def _declared_size(self, request: web.BaseRequest, peer: str) -> int | web.StreamResponse:
        """The body's size as ``request`` declares it, or the refusal of a request that is not a
        POST, declares no size (or a chunked body) or a size over the limits."""
        limits = self.limits
        if request.method != "POST":
            return self._refuse(405, peer, f"{request.method[:20]} instead of POST")
        length = request.headers.get("Content-Length")
        if length is None or "Transfer-Encoding" in request.headers:
            return self._refuse(411, peer, "no Content-Length (chunked bodies are not read)")
        try:
            size = read_digits(length, "Content-Length", limits.max_digits)
        except BoundError as exc:
            return self._refuse(400, peer, str(exc))
        if size > limits.max_body:
            return self._refuse(413, peer, f"a body of {size} octets (at most {limits.max_body})")
        return size

    async def _receive(
        self, request: web.BaseRequest, received: _Received, peer: str
    ) -> web.StreamResponse | None:
        """Read the body into ``received``, counting it as buffered; the refusal of a body that
        ends early, would overflow the bodies buffered at once or is too slow."""
        limits = self.limits
        size = received.size
        try:
            async with asyncio.timeout(limits.request_s):
                while received.got < size:
                    chunk = await request.content.read(min(size - received.got, 1 << 16))
                    if not chunk:
                        return self._refuse(
                            400, peer, f"the body ended after {received.got} of {size} octets"
                        )
                    if self._buffered + len(chunk) > limits.max_buffered:
                        return self._refuse(503, peer, f"over {limits.max_buffered} octets of bodies at once")
                    self._buffered += len(chunk)
                    received.got += len(chunk)
                    received.chunks.append(chunk)
        except TimeoutError:
            return self._refuse(408, peer, f"the body took longer than {limits.request_s:g} s")
        return None

    def _read(self, content_type: str, body: bytes, peer: str) -> None:
        """On a reader thread: the message in ``body``, given to ``deliver``."""
        self.deliver(decode_body(content_type, body, self.limits), peer)
