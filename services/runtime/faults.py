"""Fault injection in the transport (docs/faults.md).

:class:`FaultyTransport` wraps any :class:`~services.runtime.transport.Transport` of one
agent and applies, to what the agent puts on the wire:

- **message faults** per channel (C1..C8, read from the key ``roco/fipa/<channel>/…``; ``*``
  for every channel without an entry of its own): drop, duplicate, delay by ``delay_s``,
  reorder (hold one communicate and send it right after the next one to the same receiver,
  or after ``hold_s`` when no next one comes), corrupt (XOR 1–3 random bytes with random
  non-zero masks), each with its probability;
- **network faults** of the agent's own service: delay of everything it puts (egress, like
  ``tc netem delay``), loss with a probability, and partition: nothing out, nothing in, its
  liveliness tokens withdrawn (it looks gone to the others) and the others' tokens reported
  gone to it; healing declares its tokens again and reports the others as they are.

A batch (several communicates one step put on one key: shared/fipa_codec/batch.py) meets its
faults one communicate at a time, each published on its own, as if it had not been batched (the
wrapped transport may batch them again: services/runtime/backlog.py).

Faults are drawn from one ``random.Random`` seeded with ``"<seed>:<agent>"``: the same
settings and the same sequence of publications give the same faults.

Settings (:class:`FaultSettings`, JSON) come from ``ROCO_FAULTS`` at start and change at run
time through :class:`FaultUpdate` s put on ``roco/fault/control/all`` or
``roco/fault/control/<agent>`` (``roco fault``). Every applied fault is put, as a JSON
:class:`FaultEvent`, on ``roco/fault/event/<agent>``; the traffic recorder writes them to
the run folder's ``faults.jsonl``. An update carrying a ``request`` id is answered with the
agent's :class:`FaultReport` on ``roco/fault/state/<agent>``. The fault plane itself (control,
events, reports) is exempt from every fault.

Threads: ``publish`` runs on the agent's thread (or, for an idle agent's step, on the Zenoh
thread a communicate arrived on: transport.py) and, with no fault active, only tests one
attribute before calling the wrapped transport. Delayed and held communicates, fault events
and control updates are handled by one worker thread of the transport.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import random
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from typing import Annotated

import msgspec

from services.runtime.transport import AliveCallback, Callback, Transport
from shared.fipa_codec import DecodeError, decode
from shared.fipa_codec.batch import is_batch, unpack
from shared.settings import Settings

log = logging.getLogger(__name__)

FAULT_PREFIX = "roco/fault"
CONTROL_ALL = f"{FAULT_PREFIX}/control/all"
EVENT_ALL = f"{FAULT_PREFIX}/event/*"
STATE_ALL = f"{FAULT_PREFIX}/state/*"
ANY_CHANNEL = "*"
ANY_SERVICE = "*"
_FIPA = "roco/fipa/"

MESSAGE_KINDS = ("drop", "duplicate", "delay", "reorder", "corrupt")
NET_KINDS = ("net_delay", "net_loss", "partition_out", "partition_in")


def control_key(agent: str) -> str:
    """The key a fault update for ``agent`` alone is put on."""
    return f"{FAULT_PREFIX}/control/{agent}"


def event_key(agent: str) -> str:
    """The key ``agent`` puts the faults it applied on (``roco`` for process faults)."""
    return f"{FAULT_PREFIX}/event/{agent}"


def state_key(agent: str) -> str:
    """The key ``agent`` answers a fault update's ``request`` on."""
    return f"{FAULT_PREFIX}/state/{agent}"


Probability = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]
Seconds = Annotated[float, msgspec.Meta(ge=0.0, le=3600.0)]


class MessageFaults(
    msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True, omit_defaults=True
):
    """Faults of the communicates on one channel: each a probability per communicate.

    ``delay`` delays a communicate by ``delay_s``; ``reorder`` holds it until the next
    communicate to the same receiver has been sent (at most ``hold_s``)."""

    drop: Probability = 0.0
    duplicate: Probability = 0.0
    delay: Probability = 0.0
    delay_s: Seconds = 0.0
    reorder: Probability = 0.0
    hold_s: Seconds = 1.0
    corrupt: Probability = 0.0

    def active(self) -> bool:
        return bool(
            self.drop or self.duplicate or (self.delay and self.delay_s) or self.reorder or self.corrupt
        )


class NetFaults(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True, omit_defaults=True):
    """Network faults of one service: ``delay_s`` added to everything it puts, ``loss`` the
    probability that a put is lost, ``partition`` cut off in and out (tokens withdrawn)."""

    delay_s: Seconds = 0.0
    loss: Probability = 0.0
    partition: bool = False

    def active(self) -> bool:
        return bool(self.delay_s or self.loss or self.partition)


class FaultSettings(
    msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True, omit_defaults=True
):
    """All fault settings (``ROCO_FAULTS``): message faults per channel (``*``: every
    channel without an entry), network faults per service (``*``: every service without an
    entry), and the RNG seed."""

    seed: int = 0
    channels: dict[str, MessageFaults] = {}
    services: dict[str, NetFaults] = {}


class FaultUpdate(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True, omit_defaults=True):
    """A change of the settings at run time. Applied in this order: clear the named channels
    and services (``*``: all), set the given entries (replacing them), reseed when ``seed`` is
    given. A non-empty ``request`` asks for a :class:`FaultReport` with that id."""

    clear_channels: list[str] = []
    clear_services: list[str] = []
    set_channels: dict[str, MessageFaults] = {}
    set_services: dict[str, NetFaults] = {}
    seed: int | None = None
    request: str = ""


class FaultEvent(msgspec.Struct, kw_only=True, frozen=True, omit_defaults=True):
    """One applied fault. ``t``: POSIX time it was applied; ``agent``: who applied it (an
    agent, or ``roco`` for a process or container fault); ``kind``: one of
    :data:`MESSAGE_KINDS`, :data:`NET_KINDS`, ``settings`` (the agent's settings changed;
    ``detail`` holds them as JSON), ``partition``/``heal``, or a process fault (``kill``,
    ``stop``, ``start``, ``pause``, ``unpause``, ``restart``, ``net``); ``target``: the
    service a process or network fault hit. For a communicate: its ``channel``, ``key``,
    ``performative`` and ``conversation_id`` (read from the payload before any corruption)."""

    t: float
    agent: str
    kind: str
    channel: str | None = None
    key: str | None = None
    performative: str | None = None
    conversation_id: str | None = None
    target: str | None = None
    detail: str = ""


class FaultReport(msgspec.Struct, kw_only=True, frozen=True):
    """An agent's answer to a fault update with a ``request`` id: the settings in effect for
    it (``channels``, its own ``net``), and how many faults of each kind it applied."""

    agent: str
    request: str
    seed: int
    channels: dict[str, MessageFaults]
    net: NetFaults
    applied: dict[str, int]


_settings_decoder = msgspec.json.Decoder(FaultSettings)
_update_decoder = msgspec.json.Decoder(FaultUpdate)
_json = msgspec.json.Encoder()


def parse_settings(text: str | bytes) -> FaultSettings:
    """Settings from JSON; raises ValueError with one line saying what is wrong."""
    if isinstance(text, str) and not text.strip():
        return FaultSettings()
    try:
        return _settings_decoder.decode(text)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise ValueError(str(exc).splitlines()[0]) from None


def settings_from_env(environ: Mapping[str, str] | None = None) -> FaultSettings:
    """Settings from ``ROCO_FAULTS`` of ``environ`` (default ``os.environ``, read now; none
    when unset); raises ValueError when malformed."""
    return parse_settings(Settings.from_env(environ, only=("faults",)).faults)


def apply_update(settings: FaultSettings, update: FaultUpdate) -> FaultSettings:
    """``settings`` changed by ``update`` (see :class:`FaultUpdate`)."""
    channels = dict(settings.channels)
    services = dict(settings.services)
    for names, table in ((update.clear_channels, channels), (update.clear_services, services)):
        for name in names:
            if name == "*":
                table.clear()
            else:
                table.pop(name, None)
    channels.update(update.set_channels)
    services.update(update.set_services)
    seed = settings.seed if update.seed is None else update.seed
    return FaultSettings(
        seed=seed,
        channels={k: v for k, v in channels.items() if v.active()},
        services={k: v for k, v in services.items() if v.active()},
    )


def corrupt_bytes(payload: bytes, rng: random.Random) -> bytes:
    """``payload`` with 1–3 random bytes XORed with random non-zero masks (never equal to
    ``payload`` unless it is empty)."""
    if not payload:
        return payload
    buf = bytearray(payload)
    for _ in range(1 + rng.randrange(3)):
        buf[rng.randrange(len(buf))] ^= rng.randrange(1, 256)
    if bytes(buf) == payload:  # two flips of one byte cancelled out
        buf[0] ^= 0xFF
    return bytes(buf)


class _Watch:
    """One liveliness watch: what Zenoh says (``known``) and what the agent was told
    (``told``), which differ while the service is partitioned."""

    def __init__(self, callback: AliveCallback) -> None:
        self.callback = callback
        self.known: dict[str, bool] = {}
        self.told: dict[str, bool] = {}


class FaultyTransport:
    """A :class:`Transport` applying the faults of :class:`FaultSettings` to ``inner``'s
    traffic on behalf of ``agent`` (see the module docstring). ``control`` subscribes to the
    control keys; ``clock`` gives event times."""

    def __init__(
        self,
        inner: Transport,
        agent: str,
        settings: FaultSettings | None = None,
        *,
        control: bool = True,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.inner = inner
        self.agent = agent
        self._clock = clock
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        """Wakes the worker; shares ``_lock``, which guards the state below."""
        self._wlock = threading.Lock()
        self._rng = random.Random()
        self._settings = FaultSettings()
        self._channels: dict[str, MessageFaults] = {}
        self._net = NetFaults()
        self._active = False
        """True when any fault is configured for this agent: publish leaves the fast path."""
        self._partitioned = False
        self._watch_partitioned = False
        self._held: dict[str, tuple[int, bytes, int]] = {}
        """Per key: (token, payload, copies) of the communicate held for reorder."""
        self._heap: list[tuple[float, int, str, bytes | None]] = []
        """(due monotonic time, seq, key, payload) to put later; payload None: the end of a
        hold (seq is the hold's token)."""
        self._seq = itertools.count()
        self._jobs: deque[Callable[[], None]] = deque()
        self._events: deque[FaultEvent] = deque()
        self._announced: list[str] = []
        self._watches: list[_Watch] = []
        self._closed = False
        self.applied: Counter[str] = Counter()
        """Faults applied so far, per kind."""
        self._configure(settings or FaultSettings(), reseed=True)
        self._watch_partitioned = self._partitioned  # partitioned from the start: no token yet
        self._worker = threading.Thread(target=self._work, name=f"faults-{agent}", daemon=True)
        self._worker.start()
        if self._settings != FaultSettings():
            self._event("settings", detail=_json.encode(self._settings).decode())
        if control:
            inner.subscribe(CONTROL_ALL, self._on_control)
            inner.subscribe(control_key(agent), self._on_control)

    # ---- settings -------------------------------------------------------------------------
    @property
    def settings(self) -> FaultSettings:
        return self._settings

    @property
    def active(self) -> bool:
        return self._active

    def update(self, update: FaultUpdate) -> None:
        """Apply ``update`` now (never from a Zenoh callback thread: it may withdraw or
        declare liveliness tokens)."""
        with self._lock:
            before = self._partitioned
            changed = self._configure(apply_update(self._settings, update), reseed=update.seed is not None)
            after = self._partitioned
            settings = self._settings
        if before != after:
            self._set_partition(after)
        if changed:
            self._event("settings", detail=_json.encode(settings).decode())
        if update.request:
            self.inner.publish(state_key(self.agent), _json.encode(self.report(update.request)))

    def report(self, request: str = "") -> FaultReport:
        """The settings in effect for this agent and the faults applied so far."""
        with self._lock:
            return FaultReport(
                agent=self.agent,
                request=request,
                seed=self._settings.seed,
                channels=dict(self._settings.channels),
                net=self._net,
                applied=dict(self.applied),
            )

    def _configure(self, settings: FaultSettings, *, reseed: bool) -> bool:
        """Install ``settings`` (caller holds the lock or is the constructor); returns
        whether they changed."""
        changed = settings != self._settings
        self._settings = settings
        if reseed:
            self._rng.seed(f"{settings.seed}:{self.agent}")
        self._channels = {k: v for k, v in settings.channels.items() if v.active()}
        net = settings.services.get(self.agent, settings.services.get(ANY_SERVICE, NetFaults()))
        self._net = net
        self._partitioned = net.partition
        self._active = bool(self._channels) or net.active() or bool(self._held)
        return changed

    def _on_control(self, _key: str, payload: bytes) -> None:  # Zenoh thread: enqueue only
        try:
            update = _update_decoder.decode(payload)
        except (msgspec.DecodeError, msgspec.ValidationError) as exc:
            log.warning("ignored a malformed fault update: %s", str(exc).splitlines()[0])
            return
        with self._lock:
            self._jobs.append(lambda: self.update(update))
            self._cond.notify()

    # ---- outgoing -------------------------------------------------------------------------
    def publish(self, key: str, payload: bytes) -> None:
        if not self._active:
            self.inner.publish(key, payload)
            return
        if is_batch(payload) and key.startswith(_FIPA):  # faults are per communicate
            for part in unpack(payload):
                self._publish_faulty(key, part)
            return
        self._publish_faulty(key, payload)

    def _publish_faulty(self, key: str, payload: bytes) -> None:
        channel = key.split("/", 3)[2] if key.startswith(_FIPA) else None
        fired: list[tuple[str, str]] = []  # (kind, detail) of the faults applied
        with self._lock:
            sends = self._decide(key, channel, payload, fired)
            for kind, _ in fired:
                self.applied[kind] += 1
            if sends and sends[0][0] > 0:  # every send of one publication has one delay
                due = time.monotonic() + sends[0][0]
                for _, p in sends:
                    heapq.heappush(self._heap, (due, next(self._seq), key, p))
                sends = []
                self._cond.notify()
        for _, p in sends:
            self.inner.publish(key, p)
        if fired and channel is not None:  # events of communicates only
            now = self._clock()
            events = [_communicate_event(now, self.agent, k, channel, key, payload, d) for k, d in fired]
            with self._lock:
                self._events.extend(events)
                self._cond.notify()

    def _decide(
        self, key: str, channel: str | None, payload: bytes, fired: list[tuple[str, str]]
    ) -> list[tuple[float, bytes]]:
        """The faults of one publication (lock held): what to put, in order, as (delay s,
        payload); the faults applied are appended to ``fired``."""
        net = self._net
        rng = self._rng
        if net.partition:
            fired.append(("partition_out", ""))
            return []
        if net.loss and rng.random() < net.loss:
            fired.append(("net_loss", f"p={net.loss:g}"))
            return []
        mf = self._channels.get(channel, self._channels.get(ANY_CHANNEL)) if channel is not None else None
        copies, extra = 1, 0.0
        if mf is not None:
            if mf.drop and rng.random() < mf.drop:
                fired.append(("drop", f"p={mf.drop:g}"))
                return []
            if mf.corrupt and rng.random() < mf.corrupt:
                fired.append(("corrupt", f"p={mf.corrupt:g}"))
                payload = corrupt_bytes(payload, rng)
            if mf.duplicate and rng.random() < mf.duplicate:
                fired.append(("duplicate", f"p={mf.duplicate:g}"))
                copies = 2
            if mf.delay and mf.delay_s and rng.random() < mf.delay:
                fired.append(("delay", f"{mf.delay_s:g} s"))
                extra = mf.delay_s
            elif mf.reorder and key not in self._held and rng.random() < mf.reorder:
                fired.append(("reorder", f"held for the next communicate (≤ {mf.hold_s:g} s)"))
                token = next(self._seq)
                self._held[key] = (token, payload, copies)
                self._active = True
                due = time.monotonic() + mf.hold_s + net.delay_s
                heapq.heappush(self._heap, (due, token, key, None))
                self._cond.notify()
                return []
        if net.delay_s:
            fired.append(("net_delay", f"{net.delay_s:g} s"))
            extra += net.delay_s
        sends = [(extra, payload)] * copies
        held = self._held.pop(key, None)
        if held is not None:  # the held one goes right after this one
            sends += [(extra, held[1])] * held[2]
            self._refresh_active()
        return sends

    def _refresh_active(self) -> None:
        self._active = bool(self._channels) or self._net.active() or bool(self._held)

    @property
    def inline_receive(self) -> bool:
        """As the wrapped transport's (``Engine._take_here``)."""
        return bool(getattr(self.inner, "inline_receive", False))

    def more_waiting(self) -> bool:
        """As the wrapped transport's (False without one): another sample waits behind the one
        being called back on this receiving thread."""
        more = getattr(self.inner, "more_waiting", None)
        return more is not None and bool(more())

    def declared(self, key: str) -> bool:
        """As the wrapped transport's: a put on ``key`` declares nothing."""
        declared = getattr(self.inner, "declared", None)
        return declared is None or bool(declared(key))

    # ---- incoming -------------------------------------------------------------------------
    def subscribe(self, key_expr: str, callback: Callback) -> None:
        def guarded(key: str, payload: bytes) -> None:  # Zenoh thread
            if self._partitioned:
                self._dropped_in(key, payload)
                return
            callback(key, payload)

        self.inner.subscribe(key_expr, guarded)

    def _dropped_in(self, key: str, payload: bytes) -> None:
        events = []
        if key.startswith(_FIPA):  # one event per communicate, also of a batch
            channel, now = key.split("/", 3)[2], self._clock()
            events = [
                _communicate_event(now, self.agent, "partition_in", channel, key, part, "")
                for part in unpack(payload)
            ]
        with self._lock:
            self.applied["partition_in"] += max(1, len(events))
            if events:
                self._events.extend(events)
                self._cond.notify()

    @property
    def session_id(self) -> str:
        """The inner transport's session id ("" when it has none; ``Engine.counters_report``)."""
        return str(getattr(self.inner, "session_id", ""))

    # ---- liveliness -----------------------------------------------------------------------
    def announce(self, key: str) -> None:
        with self._wlock:
            self._announced.append(key)
            if self._watch_partitioned and hasattr(self.inner, "withdraw"):
                return  # declared when the partition heals
        self.inner.announce(key)

    def watch(self, key_expr: str, callback: AliveCallback) -> None:
        w = _Watch(callback)
        with self._wlock:
            self._watches.append(w)

        def changed(key: str, alive: bool) -> None:  # Zenoh thread: the callback only enqueues
            with self._wlock:
                w.known[key] = alive
                if self._watch_partitioned:
                    return
                w.told[key] = alive
                w.callback(key, alive)

        self.inner.watch(key_expr, changed)

    def _set_partition(self, on: bool) -> None:
        """Withdraw (on) or declare again (off) this agent's tokens and tell its watches the
        others are gone (on) or as they are (off). Worker or caller thread, never Zenoh's."""
        withdraw = getattr(self.inner, "withdraw", None)
        with self._wlock:
            self._watch_partitioned = on
            announced = list(self._announced)
            for w in self._watches:
                for key in sorted(set(w.known) | set(w.told)):
                    now = False if on else w.known.get(key, False)
                    if w.told.get(key, False) != now:
                        w.told[key] = now
                        w.callback(key, now)
        if withdraw is not None:  # else (a transport without it) the tokens stay declared
            for key in announced:
                if on:
                    withdraw(key)
                else:
                    self.inner.announce(key)
        self._event("partition" if on else "heal", target=self.agent)

    # ---- events and the worker ------------------------------------------------------------
    def _event(self, kind: str, *, target: str | None = None, detail: str = "") -> None:
        ev = FaultEvent(t=self._clock(), agent=self.agent, kind=kind, target=target, detail=detail)
        with self._lock:
            self._events.append(ev)
            self._cond.notify()

    def _work(self) -> None:
        while True:
            with self._lock:
                while True:
                    if self._closed:
                        return
                    now = time.monotonic()
                    if self._jobs or self._events or (self._heap and self._heap[0][0] <= now):
                        break
                    self._cond.wait(self._heap[0][0] - now if self._heap else None)
                due: list[tuple[str, bytes]] = []
                while self._heap and self._heap[0][0] <= now:
                    _, seq, key, payload = heapq.heappop(self._heap)
                    if payload is not None:
                        due.append((key, payload))
                        continue
                    held = self._held.get(key)
                    if held is not None and held[0] == seq:  # no next communicate came in time
                        del self._held[key]
                        self._refresh_active()
                        due.extend([(key, held[1])] * held[2])
                jobs = list(self._jobs)
                self._jobs.clear()
                events = list(self._events)
                self._events.clear()
            for key, payload in due:
                self._put(key, payload)
            for ev in events:
                self._put(event_key(self.agent), _json.encode(ev))
            for job in jobs:
                try:
                    job()
                except Exception:  # a bad update must not end fault handling
                    log.exception("fault update failed")

    def _put(self, key: str, payload: bytes) -> None:
        try:
            self.inner.publish(key, payload)
        except Exception as exc:  # e.g. the session closed under us at shutdown
            log.warning("fault layer could not put on %s: %s", key, exc)

    def flush(self, timeout: float = 5.0) -> bool:
        """Wait until no job or event is pending (delayed communicates excluded); returns
        False when ``timeout`` passed first. For tests and orderly shutdown."""
        done = threading.Event()

        def mark() -> None:  # worker thread, after the jobs before it
            with self._lock:
                if self._jobs or self._events:
                    self._jobs.append(mark)
                    return
            done.set()

        with self._lock:
            self._jobs.append(mark)
            self._cond.notify()
        return done.wait(timeout)

    def close(self) -> None:
        """Stop the worker (pending delayed and held communicates are lost, as when a
        process ends) after putting the pending events, then close ``inner``."""
        self.flush(timeout=2.0)
        with self._lock:
            self._closed = True
            self._cond.notify()
        self._worker.join(timeout=2.0)
        self.inner.close()


def _communicate_event(
    t: float, agent: str, kind: str, channel: str | None, key: str, payload: bytes, detail: str
) -> FaultEvent:
    performative = conversation = None
    try:
        msg = decode(payload)
        performative, conversation = msg.performative.value, msg.conversation_id
    except DecodeError:
        pass
    return FaultEvent(
        t=t,
        agent=agent,
        kind=kind,
        channel=channel,
        key=key,
        performative=performative,
        conversation_id=conversation,
        detail=detail,
    )
