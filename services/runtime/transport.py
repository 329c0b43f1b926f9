"""Transport: how buffers reach other agents. Zenoh in client mode against a router
(docs/security.md: the router is where access control applies), explicit endpoints, no
multicast scouting.

A subscription to communicates runs its callback on a receiving thread of its own, fed by
Zenoh's network threads through a FIFO with room to spare (:data:`RECEIVE_QUEUE`; never on a
network thread); other subscriptions use zenoh-python's callback threads.
A receiving thread ends only when :meth:`ZenohTransport.close` undeclares its subscription;
one that ends otherwise (an exception outside the callback's, or a BaseException out of the
callback) is logged and told to ``ZenohTransport.on_lost``, on which an agent's process ends
(services/runtime/main.py), to be started again like any crashed agent.
A communicate may be taken in there by an idle agent, whose step then puts its answers from
that thread (services/runtime/engine.py ``Engine._take_here``): a put on a key whose publisher is
declared, a few communicates at a time. A put there may wait for room in a full link, and
Zenoh goes on reading the links meanwhile: zenoh-python's own callback threads have a FIFO of
256 places, and two sessions streaming to each other while answering from those threads
deadlocked (tests/runtime/test_inline_receive.py). Declaring, and putting a stream, happen on
the agent's own thread only (calling Zenoh from inside a callback has deadlocked
in zenoh-python 1.x); the liveliness and recording callbacks only enqueue.

Communicates (``roco/fipa/**``) are put through zenoh-ext advanced publishers, one per key:
each put carries its publisher's id and a sequence number (0, 1, 2, …) and a timestamp, and
the publisher keeps its last :data:`CACHE_SAMPLES` in a cache that an advanced subscriber (the
traffic recorder) queries when it starts, when it detects a publisher that appeared before it,
and when a sequence number is missing — so a restarted recorder fills the gap it was down for,
in order, and a gap that cannot be filled shows as missing sequence numbers
(docs/recovery.md). Communicates put on a key while another thread's put on it is in progress
leave together, in one batch, after it (services/runtime/backlog.py). a_hi's reports to the
person (``roco/human/out``) go through such a publisher too, one report a put, never batched:
a person's tool that was cut off from a_hi (the router down while the agents are linked
directly) gets what it missed from that cache when it is back (services/runtime/reports.py).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from typing import NamedTuple, Protocol

import zenoh
import zenoh.ext as zext

from services.runtime import keys
from services.runtime.backlog import Backlog
from services.runtime.polling import AdaptivePoll, max_poll_us
from services.runtime.tap import Tap, fleet_group
from services.runtime.zenoh_config import Links, member_config, open_session
from shared.fipa_codec.batch import unpack

log = logging.getLogger(__name__)

Callback = Callable[[str, bytes], None]
AliveCallback = Callable[[str, bool], None]


class Arrival(NamedTuple):
    """One sample as a recording subscriber sees it: arrival time ``t`` (POSIX s), ``key``,
    ``payload``; its publisher ``source`` (``<session id>:<entity id>``) and sequence number
    ``sn`` when it came from an advanced publisher; ``t_sent`` the publisher's timestamp
    (POSIX s) when it carried one; ``late`` set by the subscriber's owner; ``part`` the
    communicate's place (0, 1, …) in the batch its sample carried (shared/fipa_codec/batch.py;
    0 for a sample of one communicate): the communicates of one batch share its ``sn``."""

    t: float
    key: str
    payload: bytes
    source: str | None = None
    sn: int | None = None
    t_sent: float | None = None
    late: bool = False
    part: int = 0


CACHE_SAMPLES = 512
"""Communicates each advanced publisher keeps for a recorder that was down (per key: one sender,
one receiver, one channel). The pour sends ≈ 280 communicates on ≈ 20 keys in ≈ 30 s, so a
recorder may be down for minutes of such traffic before anything falls out of a cache."""
HEARTBEAT_S = 1.0
"""Period (s) of a publisher's sporadic heartbeat — sent only when it has put something since
the last one — from which a subscriber learns of a communicate it missed at the end of a burst
(zenoh-ext ``MissDetectionConfig``)."""


class Transport(Protocol):
    """What the runtime needs of a transport. Three capabilities are optional, looked up by
    name (services/runtime/engine.py): ``inline_receive`` (True: subscribers are
    called back on threads of the transport's own, never inside ``publish``, so an idle agent
    may run its step there; without it every input goes to the agent's own thread),
    ``more_waiting() -> bool`` (inside such a callback: another sample waits behind this one;
    without it the agent judges a burst by the time between arrivals),
    ``declared(key) -> bool`` (a put on ``key`` declares nothing; without it every key counts
    as declared) and ``sources`` (the agent's clocks and fresh identifiers,
    services/runtime/sources.py; without it the system's)."""

    def publish(self, key: str, payload: bytes) -> None: ...
    def subscribe(self, key_expr: str, callback: Callback) -> None: ...
    def announce(self, key: str) -> None: ...
    def watch(self, key_expr: str, callback: AliveCallback) -> None: ...
    def close(self) -> None: ...


RECEIVE_QUEUE = 1 << 20
"""Samples a subscription's FIFO holds for its receiving thread before Zenoh's network thread
waits for room (zenoh-python's own callbacks have a FIFO of 256). With room, a receiving
thread that waits in a put (its link's transmission queue full) never stops Zenoh reading the
links: two agents streaming to each other while answering from their receiving threads cannot
hold each other up (tests/runtime/test_inline_receive.py). The FIFO grows only as far as it is
filled."""

MAX_KEYS = 256
"""Key expressions a :class:`ZenohTransport` keeps parsed, and keys it keeps an advanced publisher
for (communicates and a_hi's reports: an agent puts on a few keys, one per peer and channel); a
further key is parsed at each put, and what is put on it goes without cache or sequence number."""


class ZenohTransport:
    """A :class:`Transport` over one Zenoh session."""

    inline_receive = True
    """Subscribers are called back on receiving threads of their own, never inside
    :meth:`publish`: an idle agent may take a communicate in on the thread it arrived on
    (``Engine._take_here``)."""

    def __init__(
        self,
        endpoints: list[str],
        *,
        wait_for_router: bool = True,
        identity: str | None = None,
        links: Links | None = "router",
    ) -> None:
        """Open a session to ``endpoints`` as ``identity``: a client of the router, or with
        ``links`` ``peer`` (None: ``ROCO_LINKS``) a peer linked directly to the others where
        :func:`one_hop` allows (:func:`member_config`). Raises ValueError for a malformed
        ``ROCO_RECEIVE_POLL_US`` (services/runtime/polling.py) or ``ROCO_LINKS`` before opening
        anything, and for a ``ZENOH_RUNTIME`` Zenoh cannot read (:func:`open_session`)."""
        self._poll_us = max_poll_us()
        conf = member_config(endpoints, links=links, wait_for_router=wait_for_router, identity=identity)
        self.links: Links = "peer" if json.loads(conf.get_json("mode")) == "peer" else "router"
        """How this session reaches the others: ``peer`` (one hop) or ``router``."""
        self.session = open_session(conf)
        log.info("Zenoh session %s: %s links (%s)", self.session.zid(), self.links, ", ".join(endpoints))
        self._subs: list[zenoh.Subscriber | zext.AdvancedSubscriber] = []
        self._receiving: list[threading.Thread] = []
        """The receiving threads of :meth:`subscribe` (each holds its subscription)."""
        self._receiving_here = threading.local()
        """On a receiving thread: ``more``, whether a sample waits behind the one called back."""
        self._tokens: list[tuple[str, zenoh.LivelinessToken]] = []
        self._queryables: list[zenoh.Queryable[None]] = []
        self._lock = threading.Lock()
        self._keys: dict[str, zenoh.KeyExpr] = {}
        self._publishers: dict[str, zext.AdvancedPublisher] = {}
        self._declaring = threading.Lock()
        self._backlog = Backlog(self._put_on)
        """Joins the communicates that wait behind a put in progress on their key
        (services/runtime/backlog.py)."""
        self._tap = Tap.from_env(fleet_group(endpoints))
        """Where the communicates put are tapped (None: ``ROCO_TAP_DIR`` unset; services/runtime/tap.py)."""
        self._closing = False
        """Set by :meth:`close`: a receiving thread that ends now ends by its undeclaration."""
        self.on_lost: Callable[[str], None] | None = None
        """Called with why (one line), on the receiving thread, when a receiving thread of
        :meth:`subscribe` ends before :meth:`close`: its subscription receives nothing more.
        An agent's process ends on it (services/runtime/main.py); None: only logged."""
        self.lost: str | None = None
        """Why the first receiving thread that ended before :meth:`close` ended (None: none did)."""

    def publish(self, key: str, payload: bytes) -> None:
        """Put ``payload`` on ``key`` with congestion control BLOCK: when the link's queue is
        full the agent waits instead of the communicate being dropped (Zenoh's default for
        ``put`` drops after 1 ms: a burst of 5,000 communicates lost 2,000 of them;
        docs/benchmarks.md). A communicate (``roco/fipa/**``) goes through the key's advanced
        publisher (declared at its first put; see the module docstring), and so does a report
        on ``roco/human/out`` (put at once, alone); a communicate at once, on this
        thread, unless another thread's put on the key is in progress; then it waits behind it
        and leaves with what else waits there in one batch, put by that thread
        (services/runtime/backlog.py). Anything else is a
        plain put, its key expression parsed once and kept (≈ 1.2 µs instead of ≈ 3.5 µs with
        a string key). Declares only where :meth:`declared` is False: never from a Zenoh
        callback (see the module docstring). With ``ROCO_TAP_DIR`` set, a communicate is
        also appended to the tap (services/runtime/tap.py)."""
        pub = self._publishers.get(key)
        if pub is None and keys.is_cached_key(key) and len(self._publishers) < MAX_KEYS:
            pub = self._declare(key)
        if pub is not None:
            if keys.is_communicate_key(key):
                self._backlog.publish(key, payload)
            else:  # a report to the person: one JSON document a put, tapped as any plain put
                if self._tap is not None:
                    self._tap.put(time.time(), key, payload)
                pub.put(payload)
            return
        if self._tap is not None:
            self._tap.put(time.time(), key, payload)
        expr = self._keys.get(key)
        if expr is None:
            expr = zenoh.KeyExpr(key)
            if len(self._keys) < MAX_KEYS:
                self._keys[key] = expr
        self.session.put(expr, payload, congestion_control=zenoh.CongestionControl.BLOCK)

    def _put_on(self, key: str) -> Callable[[bytes], None]:
        """The put through ``key``'s advanced publisher (declared), of a communicate or a batch;
        with a tap, the tap first sees what goes on the wire, in that order."""
        put, tap = self._publishers[key].put, self._tap
        if tap is None:
            return put

        def tapped(payload: bytes) -> None:
            tap.put(time.time(), key, payload)
            put(payload)

        return tapped

    def _declare(self, key: str) -> zext.AdvancedPublisher:
        with self._declaring:  # the fault layer's worker also puts
            pub = self._publishers.get(key)
            if pub is None:
                pub = self._publishers[key] = zext.declare_advanced_publisher(
                    self.session,
                    key,
                    congestion_control=zenoh.CongestionControl.BLOCK,
                    cache=zext.CacheConfig(CACHE_SAMPLES),
                    sample_miss_detection=zext.MissDetectionConfig(
                        heartbeat=None, sporadic_heartbeat=HEARTBEAT_S
                    ),
                    publisher_detection=True,
                )
            return pub

    def declared(self, key: str) -> bool:
        """A put on ``key`` declares nothing: its publisher exists, or it needs none."""
        if key in self._publishers or not keys.is_cached_key(key):
            return True
        return len(self._publishers) >= MAX_KEYS

    @property
    def session_id(self) -> str:
        """This session's Zenoh id (hex), as the ``source`` of its communicates starts."""
        return str(self.session.zid())

    def subscribe_recovering(
        self, key_expr: str, callback: Callable[[Arrival], None], *, direct: bool = False
    ) -> None:
        """Subscribe to ``key_expr`` with a zenoh-ext advanced subscriber: ``callback`` gets
        every sample as an :class:`Arrival` (a batch of communicates as one each, in order),
        first what the advanced publishers matching it still hold in their caches (also those
        of publishers detected later), then what they put, each publisher's in order of
        sequence number, a missed one fetched again from its publisher's cache (heartbeats and
        gaps). What a publisher sends again is not filtered
        here (the caller keeps the sequence numbers it has). Runs on Zenoh's threads;
        ``direct``: as :meth:`subscribe`'s."""

        def on_sample(sample: zenoh.Sample) -> None:
            t = time.time()
            info, stamp = sample.source_info, sample.timestamp
            source = sn = None
            if info is not None:
                source, sn = f"{info.source_id.zid}:{info.source_id.eid}", info.source_sn
            sent = stamp.get_time().timestamp() if stamp is not None else None
            key, payload = str(sample.key_expr), sample.payload.to_bytes()
            parts = unpack(payload) if keys.is_communicate_key(key) else [payload]
            for part, communicate in enumerate(parts):
                callback(Arrival(t, key, communicate, source, sn, sent, part=part))

        sub = zext.declare_advanced_subscriber(
            self.session,
            key_expr,
            _on_network_thread(on_sample) if direct else on_sample,
            history=zext.HistoryConfig(detect_late_publishers=True),
            recovery=zext.RecoveryConfig(periodic_queries=None, heartbeat=True),
        )
        with self._lock:
            self._subs.append(sub)

    def subscribe(self, key_expr: str, callback: Callback, *, direct: bool = False) -> None:
        """Call ``callback(key, payload)`` for every sample on ``key_expr``, in order. For
        communicates (``roco/fipa/**``: an agent's inbox) on a receiving thread of this
        subscription's own (see the module docstring): Zenoh hands samples to it through a FIFO
        of :data:`RECEIVE_QUEUE` places, so a callback that waits (an idle agent's step putting
        into a full link) never stops Zenoh reading the link. Anything else on zenoh-python's
        callback thread of this subscription's own (the callback must only enqueue), or with
        ``direct`` on the Zenoh network thread that read the sample, so that the samples of
        several direct subscriptions reach their callbacks in the order they arrived (each
        subscription's own thread may run before another's: the recorder's sync barrier,
        services/recorder/recorder.py); the callback must only enqueue, never call Zenoh."""
        if not key_expr.startswith(keys.FIPA_PREFIX):

            def on_sample(sample: zenoh.Sample) -> None:
                callback(str(sample.key_expr), sample.payload.to_bytes())

            handler = _on_network_thread(on_sample) if direct else on_sample
            with self._lock:
                self._subs.append(self.session.declare_subscriber(key_expr, handler))
            return
        sub = self.session.declare_subscriber(key_expr, zenoh.handlers.FifoChannel(RECEIVE_QUEUE))
        waiting = AdaptivePoll(self._poll_us)
        here = self._receiving_here

        def receive() -> None:
            following: zenoh.Sample | None = None
            try:
                while True:
                    sample = following if following is not None else waiting.next(sub)
                    following = sub.try_recv()
                    here.more = following is not None
                    try:
                        callback(str(sample.key_expr), sample.payload.to_bytes())
                    except Exception:  # a callback's fault must not end the subscription
                        log.exception("subscriber callback on %s raised", key_expr)
            except BaseException as exc:
                if not self._closing:  # else: the subscriber was undeclared by close()
                    self._lose(key_expr, exc)

        thread = threading.Thread(target=receive, name=f"receive {key_expr}", daemon=True)
        with self._lock:
            self._receiving.append(thread)  # ended by the session's close: it is in recv()
        thread.start()

    def _lose(self, key_expr: str, exc: BaseException) -> None:
        """A receiving thread of :meth:`subscribe` on ``key_expr`` ends by ``exc``, not by
        :meth:`close`: logged with its traceback, kept in :attr:`lost` and told to
        :attr:`on_lost`."""
        why = f"the receiving thread of {key_expr} ended: {type(exc).__name__}: {exc}"
        log.critical("%s; nothing more is received on it", why, exc_info=exc)
        if self.lost is None:
            self.lost = why
        if self.on_lost is not None:
            self.on_lost(why)

    def serve(self, key: str, answer: Callable[[], bytes]) -> None:
        """Declare a queryable on ``key``: each query gets one reply on ``key``, the bytes of
        ``answer()``, called on Zenoh's thread (it must be quick). When ``answer`` raises, the
        query gets no reply (logged)."""

        def on_query(query: zenoh.Query) -> None:
            try:
                payload = answer()
            except Exception:
                log.exception("the answer to a query on %s failed", key)
                return
            query.reply(key, payload)

        with self._lock:
            self._queryables.append(self.session.declare_queryable(key, on_query))

    def more_waiting(self) -> bool:
        """On a receiving thread of :meth:`subscribe`, inside its callback: whether another
        sample had arrived behind the one being called back (a burst: the agent takes them in
        together on its own thread, ``Engine._on_payload``). False on any other thread."""
        return bool(getattr(self._receiving_here, "more", False))

    def announce(self, key: str) -> None:
        """Declare a liveliness token on ``key`` for the life of this transport."""
        with self._lock:
            self._tokens.append((key, self.session.liveliness().declare_token(key)))

    def withdraw(self, key: str) -> None:
        """Undeclare the liveliness tokens on ``key`` (``announce`` declares it again); used by
        the fault layer to make a partitioned agent look gone."""
        with self._lock:
            gone = [tok for k, tok in self._tokens if k == key]
            self._tokens = [(k, tok) for k, tok in self._tokens if k != key]
        for tok in gone:
            tok.undeclare()

    def watch(
        self, key_expr: str, callback: AliveCallback, *, history: bool = True, direct: bool = False
    ) -> None:
        """Call ``callback(key, alive)`` whenever a liveliness token matching ``key_expr``
        appears (True; with ``history``, tokens alive at the time of the call included) or
        disappears (False: undeclared, or its owner's session ended or was lost). Runs on
        Zenoh's threads; ``direct``: as :meth:`subscribe`'s (a token's change then reaches the
        callback in its place among the direct subscriptions' samples)."""

        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        handler = _on_network_thread(on_sample) if direct else on_sample
        with self._lock:
            sub = self.session.liveliness().declare_subscriber(key_expr, handler, history=history)
            self._subs.append(sub)

    def close(self) -> None:
        """Undeclare everything and close the session; the receiving threads end (quietly:
        by their undeclaration) and are waited for."""
        self._closing = True
        for pub in self._publishers.values():
            pub.undeclare()
        for _, tok in self._tokens:
            tok.undeclare()
        for queryable in self._queryables:
            queryable.undeclare()
        for sub in self._subs:
            sub.undeclare()
        # a subscription read by a receiving thread is held by its recv(): closing the session
        # undeclares it, and the thread's recv() then ends; it is waited for, so that it does
        # not wake into an interpreter that is shutting down (which aborts the process)
        self.session.close()
        for thread in self._receiving:
            if thread is not threading.current_thread():
                thread.join(timeout=2.0)


def _on_network_thread(on_sample: Callable[[zenoh.Sample], None]) -> zenoh.handlers.Callback[zenoh.Sample]:
    """``on_sample`` called on the Zenoh network thread that read the sample (zenoh-python's
    ``Callback`` with ``indirect=False``), not on a thread of the subscription's own."""
    return zenoh.handlers.Callback(on_sample, indirect=False)
