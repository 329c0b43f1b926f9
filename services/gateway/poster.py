"""Posting the gateway's answers to foreign platforms (FIPA SC00084), without waiting on them.

The gateway's thread hands each answer over (:meth:`Poster.submit`) and goes on; the posts run
on the event loop, in order for each foreign agent (its ``agree`` before its ``inform``) and
side by side for different ones, at most ``max_posts`` at once (a pool of connections, none
kept alive),
each with ``post_connect_s`` to connect and ``post_s`` in all; ``max_queued_posts`` more wait,
and an answer beyond them is dropped (counted ``post_dropped``). An answer is tried at its
addresses in order until one answers 200 (counted ``posted``), else counted ``post_failed``.
A peer that accepts the connection and never answers holds one post for ``post_s``, not the
gateway. Host names are resolved by a resolver that leaves out roco's own endpoints
(services/gateway/addresses.py), so a name that resolves to the gateway is not posted to.
"""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

import aiohttp
from aiohttp.abc import AbstractResolver, ResolveResult

from services.gateway.addresses import Destinations
from services.gateway.bounds import DEFAULT_LIMITS, Limits
from services.gateway.http_mtp import MTPError, MTPMessage, client_session, post
from services.gateway.loop_thread import LoopThread

__all__ = ["AsyncPost", "GuardedResolver", "PostJob", "Poster"]

log = logging.getLogger("gateway")

AsyncPost = Callable[[str, MTPMessage], Awaitable[None]]
"""How one message is posted to one address; raises MTPError, aiohttp.ClientError, OSError or
TimeoutError when it is not taken (default: services.gateway.http_mtp.post on the poster's
client)."""


@dataclass(frozen=True)
class PostJob:
    """One answer to the foreign agent ``to``: the ``addresses`` to try, in order (already
    checked: services/gateway/addresses.py), the ``message``, and ``what`` it is for the log
    (``refuse from a_co to da0@host:1099/JADE``)."""

    to: str
    addresses: tuple[str, ...]
    message: MTPMessage
    what: str


class GuardedResolver(AbstractResolver):
    """aiohttp's threaded resolver, leaving out the addresses that are roco's own endpoints;
    OSError when nothing else is left."""

    def __init__(self, destinations: Destinations) -> None:
        self._inner = aiohttp.ThreadedResolver()
        self._destinations = destinations

    async def resolve(
        self, host: str, port: int = 0, family: socket.AddressFamily = socket.AF_INET
    ) -> list[ResolveResult]:
        found = await self._inner.resolve(host, port, family)
        kept = [r for r in found if not self._destinations.is_roco(r["host"], r["port"])]
        if not kept:
            raise OSError(f"{host[:80]}:{port} resolves only to roco's own endpoints")
        return kept

    async def close(self) -> None:
        await self._inner.close()


class Poster:
    """Posts answers on ``loop`` (module docstring); ``count`` is called with ``posted``,
    ``post_failed`` and ``post_dropped`` (any thread). ``post`` replaces the HTTP client
    (tests); ``destinations`` guards its name resolution."""

    def __init__(
        self,
        loop: LoopThread,
        count: Callable[[str], None],
        *,
        limits: Limits = DEFAULT_LIMITS,
        destinations: Destinations | None = None,
        post: AsyncPost | None = None,
    ) -> None:
        self.loop = loop
        self.count = count
        self.limits = limits
        self._destinations = destinations
        self._post = post
        self._session: aiohttp.ClientSession | None = None
        self._slots = asyncio.Semaphore(limits.max_posts)
        self._queues: dict[str, deque[PostJob]] = {}  # the event loop's thread only
        self._outstanding = 0
        self._lock = threading.Lock()

    def submit(self, job: PostJob) -> None:
        """Post ``job`` (any thread; returns at once)."""
        with self._lock:
            if self._outstanding >= self.limits.max_posts + self.limits.max_queued_posts:
                full = True
            else:
                full = False
                self._outstanding += 1
        if full:
            self.count("post_dropped")
            log.warning("dropped %s: %d answers waiting to be posted", job.what, self._outstanding)
            return
        self.loop.loop.call_soon_threadsafe(self._enqueue, job)

    def _enqueue(self, job: PostJob) -> None:
        """On the loop: queue ``job`` behind the answers to the same agent, or start them."""
        waiting = self._queues.get(job.to)
        if waiting is not None:
            waiting.append(job)
            return
        self._queues[job.to] = deque([job])
        asyncio.get_running_loop().create_task(self._drain(job.to))

    async def _drain(self, to: str) -> None:
        """Post the answers to ``to`` one after the other until none is left."""
        waiting = self._queues[to]
        try:
            while waiting:
                await self._run(waiting[0])
                waiting.popleft()
        finally:
            del self._queues[to]

    def outstanding(self) -> int:
        """Answers being posted or waiting to be."""
        with self._lock:
            return self._outstanding

    async def _client(self) -> aiohttp.ClientSession:
        if self._session is None:
            resolver = GuardedResolver(self._destinations) if self._destinations is not None else None
            connector = aiohttp.TCPConnector(limit=self.limits.max_posts, force_close=True, resolver=resolver)
            self._session = client_session(self.limits, connector)
        return self._session

    async def _one(self, address: str, message: MTPMessage) -> None:
        if self._post is not None:
            async with asyncio.timeout(self.limits.post_s):
                await self._post(address, message)
            return
        await post(await self._client(), address, message)

    async def _run(self, job: PostJob) -> None:
        try:
            async with self._slots:
                for address in job.addresses:
                    try:
                        await self._one(address, job.message)
                    except (MTPError, aiohttp.ClientError, OSError, TimeoutError) as exc:
                        why = str(exc) or type(exc).__name__
                        log.warning("posting %s at %s failed: %s", job.what, address[:120], why[:200])
                        continue
                    self.count("posted")
                    log.info("%s at %s", job.what, address[:120])
                    return
                self.count("post_failed")
        finally:
            with self._lock:
                self._outstanding -= 1

    def close(self) -> None:
        """Close the client (posts under way are abandoned)."""
        if self._session is not None and not self.loop.loop.is_closed():
            session, self._session = self._session, None
            try:
                self.loop.run(session.close(), timeout=5.0)
            except (TimeoutError, RuntimeError):
                log.warning("the posting client did not close in 5 s")
