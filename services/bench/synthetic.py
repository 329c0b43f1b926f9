"""The processes of the messaging benchmark (services/bench/messaging.py): the synthetic agents
(a real :class:`~services.runtime.agent.Agent` each, on a
:class:`~services.runtime.transport.ZenohTransport`), their specification and content language,
and the bare-Zenoh processes they are compared with (an agent's Zenoh configuration, keys and,
with access control, credentials of their own: :func:`raw_names`, :func:`raw_keys`).

Kept apart from the orchestration so that a spawned benchmark process imports only what an
agent imports (the runtime, the codec, the specification's model, Zenoh): its resident memory
is an agent's, not that of the tools that started it (docs/benchmarks.md, part 6b).
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, ClassVar

import msgspec
import zenoh

from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Arc, Behaviour
from services.runtime.polling import AdaptivePoll
from services.runtime.protocol_state import ONTOLOGY
from services.runtime.transport import RECEIVE_QUEUE, Transport, ZenohTransport
from services.runtime.zenoh_config import member_config
from services.security.context import ENV_SECURITY
from services.security.context import register as register_credentials
from services.spec.model import (
    AgentSpec,
    ChannelProtocol,
    ChannelSpec,
    SystemSpec,
    default_spec,
)
from services.spec.names import FIPA_REQUEST, FIPA_SUBSCRIBE
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, encode
from shared.fipa_codec.languages import Language, encode_content, load_all
from shared.fipa_codec.languages.base import register
from shared.fipa_codec.message import new_id

BENCH_LANGUAGE = "L_BENCH"
"""The benchmark's content language (registered by the functions that use it, not on import)."""
STREAM_BATCH = 256
"""Informs the participant sends per FSM step while streaming (one output buffer)."""
WARMUP = 50
"""Round trips done and discarded before the measured ones."""
STALL_S = 3.0
"""A throughput test ends early when nothing arrived for this long (s): what is missing was lost."""
REACH = "reach"
"""The command (``("reach"[, timeout_s])``) that makes sure a pair's route exists before anything is
timed: a peer's liveliness token (or, for a bare Zenoh session, its arrival) can be known before
the route of its subscription, and a put in between reaches no one (seen with 100 agent
processes: the first request of a pair lost, its round trip never ending). An initiator sends one
request at-least-once (``retry_s`` :data:`REACH_RETRY_S`, as the fleet's agents send theirs) and
answers ``{"kind": "reach"}`` at its inform; a bare Zenoh process waits until its publisher matches
the other end's subscriber (Zenoh's matching status)."""
REACH_RETRY_S = 0.5
REACH_TIMEOUT_S = 60.0


class BenchRequest(msgspec.Struct, frozen=True, tag="bench_request"):
    """The content of a benchmark ``request``: a sequence number and ``data`` (opaque bytes)."""

    seq: int
    data: bytes


class BenchInform(msgspec.Struct, frozen=True, tag="bench_inform"):
    """The content of a benchmark ``inform`` (the answer, or one communicate of a stream)."""

    seq: int
    data: bytes


class BenchSubscription(msgspec.Struct, frozen=True, tag="bench_subscription"):
    """The content of a benchmark ``subscribe``: send ``count`` informs of ``size`` bytes, in
    batches (``Engine.batch_puts``) unless ``batched`` is False."""

    count: int
    size: int
    batched: bool = True


def _register() -> None:
    if BENCH_LANGUAGE not in load_all():
        register(Language(BENCH_LANGUAGE, ONTOLOGY, (BenchRequest, BenchInform, BenchSubscription)))


def sized_data(size: int) -> bytes:
    """``data`` such that ``BenchInform(seq=0, data=…)`` encodes to ``size`` bytes of content
    (msgpack; a larger ``seq`` adds up to 4 bytes)."""
    data = b""
    for _ in range(3):  # the bin header grows with the length: converge
        overhead = len(encode_content(BenchInform(seq=0, data=data))[1]) - len(data)
        data = b"x" * max(0, size - overhead)
    return data


def pair_names(k: int) -> tuple[str, str]:
    """The initiator and participant of synthetic pair ``k``."""
    return f"b_ini{k}", f"b_par{k}"


def raw_names(k: int) -> tuple[str, str]:
    """The identities the bare-Zenoh pinger and echo of raw pair ``k`` connect as."""
    return f"z_ini{k}", f"z_par{k}"


def raw_keys(k: int) -> tuple[str, str, str]:
    """The keys of raw pair ``k``: the pinger's puts (pings and the stream), the echo's (pongs),
    and the echo's liveliness token. They are the keys a pair of agents named
    :func:`raw_names` would use on channel ``Z<k>`` (services/runtime/keys.py), so that the
    router's and the peers' access control (services/spec_check/acl.py) check a raw put by the
    same rules as an agent's."""
    ini, par = raw_names(k)
    return keys.fipa_key(f"Z{k}", ini, par), keys.fipa_key(f"Z{k}", par, ini), keys.alive_key(par)


def bench_spec(pairs: int, raw_pairs: int = 0) -> SystemSpec:
    """A specification of ``pairs`` synthetic agent pairs, one channel ``B<k>`` each, with the
    Robot Companion's own fipa-request and fipa-subscribe definitions (who may send what, and
    their state machines come from shared/fipa_codec/protocols.py); ``raw_pairs`` more pairs
    named :func:`raw_names` on channels ``Z<k>``, whose identities the bare-Zenoh processes
    take when access control is on (the credentials and ACL are issued from this
    specification; no agent runs for them)."""
    _register()  # registered where used: importing this module changes no registry
    real = default_spec().protocols
    agents: list[AgentSpec] = []
    channels: list[ChannelSpec] = []
    named = [(f"B{k}", *pair_names(k)) for k in range(pairs)]
    named += [(f"Z{k}", *raw_names(k)) for k in range(raw_pairs)]
    for channel, ini, par in named:
        agents.append(AgentSpec(ini, ini, "services.bench.synthetic:BenchInitiator", job="benchmark"))
        agents.append(AgentSpec(par, par, "services.bench.synthetic:BenchParticipant", job="benchmark"))
        request = ChannelProtocol(
            FIPA_REQUEST,
            initiator=ini,
            languages={"request": BENCH_LANGUAGE, "inform": BENCH_LANGUAGE},
            contents={"request": ("BenchRequest",), "inform": ("BenchInform",)},
        )
        subscribe = ChannelProtocol(
            FIPA_SUBSCRIBE,
            initiator=ini,
            languages={"subscribe": BENCH_LANGUAGE, "inform": BENCH_LANGUAGE},
            contents={"subscribe": ("BenchSubscription",), "inform": ("BenchInform",)},
        )
        channels.append(ChannelSpec(channel, (ini, par), "benchmark communicates", (request, subscribe)))
    return SystemSpec(
        system="bench",
        agents=tuple(agents),
        protocols={p: real[p] for p in (FIPA_REQUEST, FIPA_SUBSCRIBE)},
        channels=tuple(channels),
    )


def request_bytes(size: int) -> int:
    """Length (B) of roco's encoded request communicate with ``size`` bytes of content, as
    :meth:`Engine.send` builds it (the raw Zenoh payload is made this long)."""
    _register()  # registered where used: importing this module changes no registry
    language, body = encode_content(BenchRequest(seq=1, data=sized_data(size)))
    msg = Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("b_ini0"),
        receiver=(AgentIdentifier("b_par0"),),
        content=body,
        language=language,
        encoding="msgpack",
        ontology=ONTOLOGY,
        protocol=FIPA_REQUEST,
        conversation_id=new_id("c-"),
        reply_with=new_id("b_ini0-"),
    )
    return len(encode(msg))


# ---------------------------------------------------------------------------------- agents
class BenchInitiator(Agent):
    """Plays the initiator: takes commands from the benchmark (receptor events, through its
    pipe) and reports results on it. ``("pingpong", n, size)``: ``WARMUP + n`` request/inform
    round trips, one at a time; ``("stream", n, size)``: subscribe for ``n`` informs;
    ``("reach",)``: one request sent at-least-once (:data:`REACH`)."""

    name: ClassVar[str] = "b_ini0"

    def __init__(self, transport: Transport, spec: SystemSpec, results: Connection) -> None:
        self.results = results
        self.peer = "b_par" + self.name.removeprefix("b_ini")
        self.commands: deque[tuple[Any, ...]] = deque()
        self.job: tuple[Any, ...] | None = None
        self.samples: list[float] = []
        self.ends: list[float] = []
        """time.perf_counter() (CLOCK_MONOTONIC: one clock for the host's processes) at which
        each measured round trip ended."""
        self.done = 0
        self.data = b""
        self.conversation = ""
        self.outstanding = False
        self.t0 = 0.0
        self.count = 0
        self.t_first = 0.0
        self.first = 0
        self.t_last = 0.0
        super().__init__(transport, spec)

    def build_fsm(self) -> FSM:
        work = Behaviour("work", self._work, terminal=lambda: False, doc="run the benchmark's commands")
        return FSM([work], [Arc("work", "work")])

    def _work(self) -> None:
        while self.r:
            cmd = self.r.popleft()
            if cmd is not None and not answer_counters(self, self.results, cmd):
                self.commands.append(cmd)
        if self.job is None and self.commands and self.peer in self.peers:
            self._start(self.commands.popleft())
        if self.job is None:
            self.engine.x.clear()
        elif self.job[0] == "pingpong":
            self._pingpong()
        elif self.job[0] == REACH:
            self._reach()
        else:
            self._count()

    def _start(self, cmd: tuple[Any, ...]) -> None:
        if cmd[0] == REACH:
            self._reach_start(cmd)
            return
        kind, n, size, *rest = cmd  # ("stream", n, size, False): informs one put each
        self.job = cmd
        self.samples = []
        self.ends = []
        self.done = 0
        self.count = 0
        self.outstanding = False
        self.data = sized_data(size)
        self.t0 = time.perf_counter()
        if kind == "stream":
            msg = self.engine.send(
                self.peer,
                Performative.SUBSCRIBE,
                BenchSubscription(count=n, size=size, batched=bool(rest[0]) if rest else True),
                protocol=FIPA_SUBSCRIBE,
                expect_reply=True,
            )
            self.conversation = msg.conversation_id or ""

    def _reach_start(self, cmd: tuple[Any, ...]) -> None:
        """One request to the peer, retransmitted until answered (:data:`REACH`)."""
        self.job = cmd
        msg = self.engine.send(
            self.peer,
            Performative.REQUEST,
            BenchRequest(seq=-1, data=b""),
            protocol=FIPA_REQUEST,
            expect_reply=True,
            retry_s=REACH_RETRY_S,
        )
        self.conversation = msg.conversation_id or ""

    def _reach(self) -> None:
        while self.engine.x:
            item = self.engine.x.popleft()
            if item.msg.conversation_id != self.conversation:
                continue
            if item.performative is Performative.INFORM:
                self._finish({"kind": REACH})
            else:
                self._finish({"error": f"{item.performative.value} from {item.sender} to a request"})
            return

    def _finish(self, result: dict[str, Any]) -> None:
        self.results.send(result)
        self.job = None

    def _pingpong(self) -> None:
        assert self.job is not None
        n = self.job[1]
        while self.engine.x:
            item = self.engine.x.popleft()
            if item.performative is not Performative.INFORM:  # not-understood, refuse, failure
                self._finish({"error": f"{item.performative.value} from {item.sender} to a request"})
                return
            if self.outstanding and item.msg.conversation_id == self.conversation:
                self.outstanding = False
                self.done += 1
                if self.done > WARMUP:
                    now = time.perf_counter()
                    self.samples.append(now - self.t0)
                    self.ends.append(now)
        if self.outstanding:
            return
        if self.done >= WARMUP + n:
            self._finish({"kind": "pingpong", "samples_s": self.samples, "ends_s": self.ends})
            return
        self.t0 = time.perf_counter()
        msg = self.engine.send(
            self.peer,
            Performative.REQUEST,
            BenchRequest(seq=self.done, data=self.data),
            protocol=FIPA_REQUEST,
            expect_reply=True,
        )
        self.conversation = msg.conversation_id or ""
        self.outstanding = True

    def _count(self) -> None:
        assert self.job is not None
        n = self.job[1]
        now = time.perf_counter()  # every inform of this step was taken in by now
        before = self.count
        refused = self._take_informs()
        if refused is not None:
            self._finish({"error": refused})
            return
        if self.count > before:
            if before == 0:  # the rate counts what arrived after the first step that saw any
                self.t_first, self.first = now, self.count
            self.t_last = now
        stalled = now - (self.t_last if self.count else self.t0) > STALL_S
        if self.count >= n or stalled:
            span = self.t_last - self.t_first
            self._finish(
                {"kind": "stream", "count": self.count, "first": self.first, "span_s": span, "sent": n}
            )

    def _take_informs(self) -> str | None:
        """Count the stream's informs in the input buffer; what ended the stream instead (a
        not-understood, refuse or failure to the subscribe), or None."""
        while self.engine.x:
            item = self.engine.x.popleft()
            if item.performative is Performative.INFORM and item.msg.conversation_id == self.conversation:
                self.count += 1
            elif item.performative is not Performative.AGREE:
                return f"{item.performative.value} from {item.sender} to a subscribe"
        return None


class BenchParticipant(Agent):
    """Plays the participant: answers each request with an inform echoing its content; on a
    subscribe, agrees and streams the informs asked for, :data:`STREAM_BATCH` per step."""

    name: ClassVar[str] = "b_par0"

    def __init__(self, transport: Transport, spec: SystemSpec, results: Connection) -> None:
        self.results = results
        self.stream: Any = None
        self.left = 0
        self.data = b""
        super().__init__(transport, spec)

    def build_fsm(self) -> FSM:
        serve = Behaviour("serve", self._serve, terminal=lambda: self.stream is not None)
        stream = Behaviour("stream", self._stream, terminal=lambda: self.stream is None, waits=False)
        arcs = [
            Arc("serve", "stream", lambda: self.stream is not None),
            Arc("serve", "serve"),
            Arc("stream", "serve"),
        ]
        return FSM([serve, stream], arcs)

    def _serve(self) -> None:
        while self.r:
            cmd = self.r.popleft()
            if cmd is not None:
                answer_counters(self, self.results, cmd)
        while self.engine.x:
            item = self.engine.x.popleft()
            content = item.content
            if item.performative is Performative.REQUEST and isinstance(content, BenchRequest):
                self.engine.reply(item, Performative.INFORM, BenchInform(seq=content.seq, data=content.data))
            elif item.performative is Performative.SUBSCRIBE and isinstance(content, BenchSubscription):
                self.engine.reply(item, Performative.AGREE)
                self.stream, self.left, self.data = item, content.count, sized_data(content.size)
                self.batch_puts = content.batched

    def _stream(self) -> None:
        batch = min(STREAM_BATCH, self.left)
        for i in range(batch):
            self.engine.reply(
                self.stream, Performative.INFORM, BenchInform(seq=self.left - i, data=self.data)
            )
        self.left -= batch
        if self.left <= 0:
            self.stream = None


COUNTERS = "counters"
"""The command (``("counters",)``) a synthetic agent answers with its counters, from its own
thread between two steps: ``{"kind": "counters", "counters": {name: count}}``
(services/runtime/counters.py names them)."""


def answer_counters(agent: Agent, results: Connection, cmd: tuple[Any, ...]) -> bool:
    """Send ``agent``'s counters on ``results`` when ``cmd`` asks for them; True if it did."""
    if cmd[0] != COUNTERS:
        return False
    results.send({"kind": COUNTERS, "counters": dict(agent.counters)})
    return True


def use_credentials(endpoint: str, security: str | None) -> None:
    """In a spawned process: sessions to ``endpoint`` authenticate with the credentials folder
    ``security`` (services/security/context.py), or with none when it is None, whatever
    ``ROCO_SECURITY`` the process inherited."""
    os.environ.pop(ENV_SECURITY, None)
    register_credentials(endpoint, Path(security) if security is not None else None)


def agent_process(
    name: str, pairs: int, endpoint: str, conn: Connection, security: str | None = None
) -> None:
    """Body of one synthetic agent process (spawned): run agent ``name`` of
    :func:`bench_spec` ``(pairs)`` on the router at ``endpoint``, authenticated as ``name``
    with the credentials folder ``security`` (None: no access control); commands arrive on
    ``conn`` (``("stop",)`` ends it), results leave on it."""
    logging.basicConfig(level=logging.ERROR)
    use_credentials(endpoint, security)
    spec = bench_spec(pairs)
    base: type[Agent] = BenchInitiator if name.startswith("b_ini") else BenchParticipant
    cls = type(name, (base,), {"name": name})
    transport = ZenohTransport([endpoint], links=None, identity=name)
    agent = cls(transport, spec, conn)
    agent.engine.bind()
    serve(agent, transport, conn)


def serve(
    agent: Agent,
    transport: ZenohTransport,
    conn: Connection,
    on_command: Callable[[tuple[Any, ...]], bool] | None = None,
) -> None:
    """Run a bound synthetic ``agent`` until told to stop: a thread reads commands from
    ``conn`` (``("stop",)`` or a closed pipe ends the agent; ``on_command`` may take one and
    return True, else the agent gets it with ``post``); says ``("ready", pid)`` on ``conn``
    first and closes ``transport`` at the end."""

    def read() -> None:
        while True:
            try:
                cmd = conn.recv()
            except (EOFError, OSError):
                cmd = ("stop",)
            if cmd[0] == "stop":
                agent.engine.stop()
                return
            if on_command is None or not on_command(cmd):
                agent.post(cmd)

    threading.Thread(target=read, name="bench-commands", daemon=True).start()
    conn.send(("ready", os.getpid()))
    try:
        agent.engine.run()
    finally:
        transport.close()


# ------------------------------------------------------------------------------- raw Zenoh
def raw_process(role: str, k: int, endpoint: str, conn: Connection, security: str | None = None) -> None:
    """Body of one bare-Zenoh process (spawned), with the configuration of an agent's session
    (:func:`~services.runtime.zenoh_config.member_config`: the same links, and with ``security``,
    the credentials folder, the same mutual TLS, password and access control), connected as
    :func:`raw_names` ``(k)`` on the keys :func:`raw_keys` ``(k)``. ``role`` "echo": puts
    every ping back, or counts them while armed for a stream; "pinger": does the ping-pong
    and sends the stream. Commands on ``conn``: ``("pingpong", n, size[, poll_us])``,
    ``("send", n, size)`` (pinger), ``("arm", n)``, ``("poll", max_us)`` (echo), ``("reach",)``
    (both: :data:`REACH`), ``("stop",)``.
    ``poll_us``/``max_us`` > 0: wait for each sample as roco's receiving threads do
    (services/runtime/polling.py) instead of in a blocking ``recv()``."""
    use_credentials(endpoint, security)
    identity = raw_names(k)[0 if role == "pinger" else 1]
    session = zenoh.open(member_config([endpoint], identity=identity))
    ping, pong, alive = raw_keys(k)
    try:
        if role == "echo":
            _raw_echo(session, conn, ping, pong, alive)
        else:
            _raw_pinger(session, conn, ping, pong, alive)
    finally:
        session.close()


def matched(publisher: zenoh.Publisher, timeout: float) -> bool:
    """Whether ``publisher`` matches a subscriber (Zenoh's matching status: a put would be
    routed to one), waiting up to ``timeout`` s for the status to change."""
    now = threading.Event()

    def on_status(status: zenoh.MatchingStatus) -> None:
        if status.matching:
            now.set()

    listener = publisher.declare_matching_listener(on_status)
    try:
        status: Any = publisher.matching_status  # a MatchingStatus (zenoh's stub says bool)
        return bool(getattr(status, "matching", status)) or now.wait(timeout)
    finally:
        listener.undeclare()


def _reached(publisher: zenoh.Publisher, other: str, cmd: tuple[Any, ...]) -> dict[str, Any]:
    """The answer to ``cmd`` (``("reach"[, timeout_s])``, :data:`REACH`) of a bare Zenoh process
    whose ``publisher`` goes to ``other``."""
    timeout = float(cmd[1]) if len(cmd) > 1 else REACH_TIMEOUT_S
    if matched(publisher, timeout):
        return {"kind": REACH}
    return {"error": f"no subscriber of {other} matched within {timeout:g} s"}


def _raw_echo(session: zenoh.Session, conn: Connection, ping: str, pong: str, alive: str) -> None:
    """One subscriber's FIFO on ``ping`` (as large as an agent's inbox's), read by one thread
    as an agent's receiving thread reads its inbox: each sample is put back on ``pong``, or,
    while armed for a stream, counted and stamped."""
    pings = session.declare_subscriber(ping, zenoh.handlers.FifoChannel(RECEIVE_QUEUE))
    state = {"count": 0, "want": 0, "first": 0.0, "last": 0.0}
    armed = threading.Event()
    complete = threading.Event()
    ponger = session.declare_publisher(pong, congestion_control=zenoh.CongestionControl.BLOCK)
    polling: list[AdaptivePoll | None] = [None]
    """How the echo waits for a ping: None, a blocking ``recv()``; else polling as roco's
    receiving threads do (``("poll", max_us)`` sets it)."""

    def take() -> None:
        with contextlib.suppress(Exception):  # ends when the subscriber is undeclared
            while True:
                poll = polling[0]
                sample = pings.recv() if poll is None else poll.next(pings)
                if not armed.is_set():
                    ponger.put(sample.payload.to_bytes())
                    continue
                now = time.perf_counter()
                if state["count"] == 0:
                    state["first"] = now
                state["count"] += 1
                state["last"] = now
                if state["count"] >= state["want"]:
                    armed.clear()
                    complete.set()

    threading.Thread(target=take, name="raw-echo", daemon=True).start()
    token = session.liveliness().declare_token(alive)
    conn.send(("ready", os.getpid()))
    while True:
        cmd = conn.recv()
        if cmd[0] == "stop":
            break
        if cmd[0] == "poll":
            polling[0] = AdaptivePoll(cmd[1]) if cmd[1] > 0 else None
            conn.send(("polling", cmd[1]))
            continue
        if cmd[0] == REACH:
            conn.send(_reached(ponger, "the pinger", cmd))
            continue
        complete.clear()
        state.update(count=0, want=cmd[1], first=0.0, last=0.0)
        armed.set()
        conn.send(("armed",))
        t0 = time.perf_counter()
        while not complete.wait(0.5):
            last = state["last"] if state["count"] else t0
            if time.perf_counter() - last > STALL_S:
                break
        armed.clear()
        span = state["last"] - state["first"]  # one sample per stamp: one at the first stamp
        conn.send({"kind": "stream", "count": state["count"], "first": 1, "span_s": span})
    token.undeclare()
    ponger.undeclare()


def _raw_pingpong(pinger: Any, pongs: Any, payload: bytes, n: int, poll_us: list[Any]) -> dict[str, Any]:
    """``n`` timed round trips after ``WARMUP`` ones; pongs polled (``AdaptivePoll``) when
    ``poll_us`` holds a positive figure, else received blocking."""
    poll = AdaptivePoll(poll_us[0]) if poll_us and poll_us[0] > 0 else None
    samples, ends = [], []
    for i in range(WARMUP + n):
        t0 = time.perf_counter()
        pinger.put(payload)
        if poll is None:
            pongs.recv()
        else:
            poll.next(pongs)
        if i >= WARMUP:
            end = time.perf_counter()
            samples.append(end - t0)
            ends.append(end)
    return {"kind": "pingpong", "samples_s": samples, "ends_s": ends}


def _raw_stream(publisher: Any, payload: bytes, n: int) -> dict[str, Any]:
    """``n`` puts as fast as they go, and how long they took."""
    t0 = time.perf_counter()
    for _ in range(n):
        publisher.put(payload)
    return {"kind": "sent", "seconds": time.perf_counter() - t0}


def _raw_pinger(session: zenoh.Session, conn: Connection, ping: str, pong: str, alive: str) -> None:
    pongs = session.declare_subscriber(pong, zenoh.handlers.FifoChannel(RECEIVE_QUEUE))
    present = threading.Event()

    def on_alive(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            present.set()

    watch = session.liveliness().declare_subscriber(alive, on_alive, history=True)
    # congestion control BLOCK, as roco's ZenohTransport: nothing is dropped on either side
    pinger = session.declare_publisher(ping, congestion_control=zenoh.CongestionControl.BLOCK)
    conn.send(("ready", os.getpid()))
    while True:
        cmd = conn.recv()
        if cmd[0] == "stop":
            break
        if cmd[0] == REACH:
            conn.send(_reached(pinger, "the echo", cmd))
            continue
        if not present.wait(30):
            conn.send({"error": "the echo process never appeared"})
            continue
        kind, n, size, *rest = cmd
        payload = b"p" * size
        if kind == "pingpong":
            conn.send(_raw_pingpong(pinger, pongs, payload, n, rest))
        else:
            conn.send(_raw_stream(pinger, payload, n))
    pinger.undeclare()
    watch.undeclare()
    pongs.undeclare()
