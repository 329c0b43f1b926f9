"""Messaging benchmark (issue 9, parts 2 and 8): roco's runtime against bare Zenoh, through one
router, measured side by side in the same run.

**roco**: two (or more) synthetic agents, each a real :class:`services.runtime.agent.Agent` in
its own process on a :class:`~services.runtime.transport.ZenohTransport` (client mode, explicit
loopback endpoint, no multicast scouting), started with ``multiprocessing`` *spawn*. They
follow a small specification built here (:func:`bench_spec`: one channel ``B<k>`` per pair,
the real ``fipa-request`` and ``fipa-subscribe`` protocol definitions of the Robot
Companion's specification) and talk in a content language registered here, ``L_BENCH``
(ontology O_RoCo), whose terms carry an opaque ``data`` field sized so that the content of
each communicate is the requested number of bytes. Every communicate goes through the whole
send and receive path: interface and protocol-state checks, content encoding, the msgpack
envelope (shared/fipa_codec), dedup digest, decoding, validation against the interface and
the content schema, the agent's input queue and FSM step.

- *round trip*: the initiator sends a ``request`` (fipa-request, a new conversation each time,
  ``expect_reply``) and the participant answers with an ``inform`` echoing the content; the
  time is taken (``time.perf_counter``) from the initiator's ``send`` call to the transition in
  which the inform is in its input buffer.
- *one-way throughput*: the initiator ``subscribe``s (fipa-subscribe) for ``n`` communicates;
  the participant ``agree``s and then sends ``n`` ``inform``s in the same conversation, 256
  per FSM step; the initiator counts the informs that reach its input buffer and divides
  ``count - 1`` by the time from the first to the last.

**raw Zenoh**: two more Python processes with a bare session each (same client configuration,
same router): a ping-pong (``put`` on a key, the other process receives it from a subscriber's
FIFO handler and ``put``s it back) and a throughput test (``put`` ``n`` payloads in a loop; a
subscriber callback on the other side counts them). The payload has the size of roco's
encoded request communicate (envelope included), so the ratio is the runtime's cost.

The parent process only orchestrates (pipes to each child, no sleeps for synchronisation:
children report ``ready``, the initiators wait for their peer's liveliness token); every wait
has a timeout, and only the processes started here are ended, by their PID.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing as mp
import os
import shutil
import statistics
import tempfile
import threading
import time
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any, ClassVar

import msgspec
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Arc, Behaviour
from services.runtime.conversations import ONTOLOGY
from services.runtime.transport import Transport, ZenohTransport, client_config
from services.spec.model import (
    AgentSpec,
    ChannelProtocol,
    ChannelSpec,
    SystemSpec,
    default_spec,
)
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


class BenchRequest(msgspec.Struct, frozen=True, tag="bench_request"):
    """The content of a benchmark ``request``: a sequence number and ``data`` (opaque bytes)."""

    seq: int
    data: bytes


class BenchInform(msgspec.Struct, frozen=True, tag="bench_inform"):
    """The content of a benchmark ``inform`` (the answer, or one communicate of a stream)."""

    seq: int
    data: bytes


class BenchSubscription(msgspec.Struct, frozen=True, tag="bench_subscription"):
    """The content of a benchmark ``subscribe``: send ``count`` informs of ``size`` bytes."""

    count: int
    size: int


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


def bench_spec(pairs: int) -> SystemSpec:
    """A specification of ``pairs`` synthetic agent pairs, one channel ``B<k>`` each, with the
    Robot Companion's own fipa-request and fipa-subscribe definitions (who may send what, and
    their state machines come from shared/fipa_codec/protocols.py)."""
    _register()  # registered where used: importing this module changes no registry
    real = default_spec().protocols
    agents: list[AgentSpec] = []
    channels: list[ChannelSpec] = []
    for k in range(pairs):
        ini, par = pair_names(k)
        agents.append(AgentSpec(ini, ini, "services.bench.messaging:BenchInitiator", job="benchmark"))
        agents.append(AgentSpec(par, par, "services.bench.messaging:BenchParticipant", job="benchmark"))
        request = ChannelProtocol(
            "fipa-request",
            initiator=ini,
            languages={"request": BENCH_LANGUAGE, "inform": BENCH_LANGUAGE},
            contents={"request": ("BenchRequest",), "inform": ("BenchInform",)},
        )
        subscribe = ChannelProtocol(
            "fipa-subscribe",
            initiator=ini,
            languages={"subscribe": BENCH_LANGUAGE, "inform": BENCH_LANGUAGE},
            contents={"subscribe": ("BenchSubscription",), "inform": ("BenchInform",)},
        )
        channels.append(ChannelSpec(f"B{k}", (ini, par), "benchmark communicates", (request, subscribe)))
    return SystemSpec(
        system="bench",
        agents=tuple(agents),
        protocols={p: real[p] for p in ("fipa-request", "fipa-subscribe")},
        channels=tuple(channels),
    )


def request_bytes(size: int) -> int:
    """Length (B) of roco's encoded request communicate with ``size`` bytes of content, as
    :meth:`Agent.send` builds it (the raw Zenoh payload is made this long)."""
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
        protocol="fipa-request",
        conversation_id=new_id("c-"),
        reply_with=new_id("b_ini0-"),
    )
    return len(encode(msg))


# ---------------------------------------------------------------------------------- agents
class BenchInitiator(Agent):
    """Plays the initiator: takes commands from the benchmark (receptor events, through its
    pipe) and reports results on it. ``("pingpong", n, size)``: ``WARMUP + n`` request/inform
    round trips, one at a time; ``("stream", n, size)``: subscribe for ``n`` informs."""

    name: ClassVar[str] = "b_ini0"

    def __init__(self, transport: Transport, spec: SystemSpec, results: Connection) -> None:
        self.results = results
        self.peer = "b_par" + self.name.removeprefix("b_ini")
        self.commands: deque[tuple[Any, ...]] = deque()
        self.job: tuple[Any, ...] | None = None
        self.samples: list[float] = []
        self.done = 0
        self.data = b""
        self.conversation = ""
        self.outstanding = False
        self.t0 = 0.0
        self.count = 0
        self.t_first = 0.0
        self.t_last = 0.0
        super().__init__(transport, spec)

    def build_fsm(self) -> FSM:
        work = Behaviour("work", self._work, terminal=lambda: False, doc="run the benchmark's commands")
        return FSM("work", {"work": work}, [Arc("work", "work")])

    def _work(self) -> None:
        while self.r:
            cmd = self.r.popleft()
            if cmd is not None:
                self.commands.append(cmd)
        if self.job is None and self.commands and self.peer in self.peers:
            self._start(self.commands.popleft())
        if self.job is None:
            self.x.clear()
        elif self.job[0] == "pingpong":
            self._pingpong()
        else:
            self._count()

    def _start(self, cmd: tuple[Any, ...]) -> None:
        kind, n, size = cmd
        self.job = cmd
        self.samples = []
        self.done = 0
        self.count = 0
        self.outstanding = False
        self.data = sized_data(size)
        self.t0 = time.perf_counter()
        if kind == "stream":
            msg = self.send(
                self.peer,
                Performative.SUBSCRIBE,
                BenchSubscription(count=n, size=size),
                protocol="fipa-subscribe",
                expect_reply=True,
            )
            self.conversation = msg.conversation_id or ""

    def _finish(self, result: dict[str, Any]) -> None:
        self.results.send(result)
        self.job = None

    def _pingpong(self) -> None:
        assert self.job is not None
        n = self.job[1]
        while self.x:
            item = self.x.popleft()
            if (
                item.performative is Performative.INFORM
                and self.outstanding
                and item.msg.conversation_id == self.conversation
            ):
                self.outstanding = False
                self.done += 1
                if self.done > WARMUP:
                    self.samples.append(time.perf_counter() - self.t0)
        if self.outstanding:
            return
        if self.done >= WARMUP + n:
            self._finish({"kind": "pingpong", "samples_s": self.samples})
            return
        self.t0 = time.perf_counter()
        msg = self.send(
            self.peer,
            Performative.REQUEST,
            BenchRequest(seq=self.done, data=self.data),
            protocol="fipa-request",
            expect_reply=True,
        )
        self.conversation = msg.conversation_id or ""
        self.outstanding = True

    def _count(self) -> None:
        assert self.job is not None
        n = self.job[1]
        while self.x:
            item = self.x.popleft()
            if item.performative is Performative.INFORM and item.msg.conversation_id == self.conversation:
                now = time.perf_counter()
                if self.count == 0:
                    self.t_first = now
                self.count += 1
                self.t_last = now
        now = time.perf_counter()
        stalled = now - (self.t_last if self.count else self.t0) > STALL_S
        if self.count >= n or stalled:
            self._finish(
                {"kind": "stream", "count": self.count, "span_s": self.t_last - self.t_first, "sent": n}
            )


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
        return FSM("serve", {"serve": serve, "stream": stream}, arcs)

    def _serve(self) -> None:
        self.r.clear()
        while self.x:
            item = self.x.popleft()
            content = item.content
            if item.performative is Performative.REQUEST and isinstance(content, BenchRequest):
                self.reply(item, Performative.INFORM, BenchInform(seq=content.seq, data=content.data))
            elif item.performative is Performative.SUBSCRIBE and isinstance(content, BenchSubscription):
                self.reply(item, Performative.AGREE)
                self.stream, self.left, self.data = item, content.count, sized_data(content.size)

    def _stream(self) -> None:
        batch = min(STREAM_BATCH, self.left)
        for i in range(batch):
            self.reply(self.stream, Performative.INFORM, BenchInform(seq=self.left - i, data=self.data))
        self.left -= batch
        if self.left <= 0:
            self.stream = None


def agent_process(name: str, pairs: int, endpoint: str, conn: Connection) -> None:
    """Body of one synthetic agent process (spawned): run agent ``name`` of
    :func:`bench_spec` ``(pairs)`` on the router at ``endpoint``; commands arrive on ``conn``
    (``("stop",)`` ends it), results leave on it."""
    logging.basicConfig(level=logging.ERROR)
    spec = bench_spec(pairs)
    base: type[Agent] = BenchInitiator if name.startswith("b_ini") else BenchParticipant
    cls = type(name, (base,), {"name": name})
    transport = ZenohTransport([endpoint])
    agent = cls(transport, spec, conn)
    agent.bind()

    def read() -> None:
        while True:
            try:
                cmd = conn.recv()
            except (EOFError, OSError):
                cmd = ("stop",)
            if cmd[0] == "stop":
                agent.stop()
                return
            agent.post(cmd)

    threading.Thread(target=read, name="bench-commands", daemon=True).start()
    conn.send(("ready", os.getpid()))
    try:
        agent.run()
    finally:
        transport.close()


# ------------------------------------------------------------------------------- raw Zenoh
def raw_process(role: str, k: int, endpoint: str, conn: Connection) -> None:
    """Body of one bare-Zenoh process (spawned). ``role`` "echo": puts every ping back and
    counts throughput payloads in a subscriber callback; "pinger": does the ping-pong and
    sends the throughput payloads. Commands on ``conn``: ``("pingpong", n, size)``,
    ``("send", n, size)`` (pinger), ``("arm", n)`` (echo), ``("stop",)``."""
    session = zenoh.open(client_config([endpoint]))
    ping, pong, tput = f"bench/raw/{k}/ping", f"bench/raw/{k}/pong", f"bench/raw/{k}/tput"
    alive = f"bench/raw/{k}/alive"
    try:
        if role == "echo":
            _raw_echo(session, conn, ping, pong, tput, alive)
        else:
            _raw_pinger(session, conn, ping, pong, tput, alive)
    finally:
        session.close()


def _raw_echo(session: zenoh.Session, conn: Connection, ping: str, pong: str, tput: str, alive: str) -> None:
    pings = session.declare_subscriber(ping)
    state = {"count": 0, "want": 0, "first": 0.0, "last": 0.0}
    complete = threading.Event()

    def on_tput(sample: zenoh.Sample) -> None:
        now = time.perf_counter()
        if state["count"] == 0:
            state["first"] = now
        state["count"] += 1
        state["last"] = now
        if state["count"] >= state["want"]:
            complete.set()

    counter = session.declare_subscriber(tput, on_tput)

    ponger = session.declare_publisher(pong, congestion_control=zenoh.CongestionControl.BLOCK)

    def echo() -> None:
        with contextlib.suppress(Exception):  # ends when the subscriber is undeclared
            while True:
                ponger.put(pings.recv().payload.to_bytes())

    threading.Thread(target=echo, name="raw-echo", daemon=True).start()
    token = session.liveliness().declare_token(alive)
    conn.send(("ready", os.getpid()))
    while True:
        cmd = conn.recv()
        if cmd[0] == "stop":
            break
        complete.clear()
        state.update(count=0, want=cmd[1], first=0.0, last=0.0)
        conn.send(("armed",))
        t0 = time.perf_counter()
        while not complete.wait(0.5):
            last = state["last"] if state["count"] else t0
            if time.perf_counter() - last > STALL_S:
                break
        conn.send({"kind": "stream", "count": state["count"], "span_s": state["last"] - state["first"]})
    token.undeclare()
    counter.undeclare()  # the echo thread's subscriber goes with the session


def _raw_pinger(
    session: zenoh.Session, conn: Connection, ping: str, pong: str, tput: str, alive: str
) -> None:
    pongs = session.declare_subscriber(pong)
    present = threading.Event()

    def on_alive(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            present.set()

    watch = session.liveliness().declare_subscriber(alive, on_alive, history=True)
    # congestion control BLOCK, as roco's ZenohTransport: nothing is dropped on either side
    block = zenoh.CongestionControl.BLOCK
    publisher = session.declare_publisher(tput, congestion_control=block)
    pinger = session.declare_publisher(ping, congestion_control=block)
    conn.send(("ready", os.getpid()))
    while True:
        cmd = conn.recv()
        if cmd[0] == "stop":
            break
        if not present.wait(30):
            conn.send({"error": "the echo process never appeared"})
            continue
        kind, n, size = cmd
        payload = b"p" * size
        if kind == "pingpong":
            samples = []
            for i in range(WARMUP + n):
                t0 = time.perf_counter()
                pinger.put(payload)
                pongs.recv()
                if i >= WARMUP:
                    samples.append(time.perf_counter() - t0)
            conn.send({"kind": "pingpong", "samples_s": samples})
        else:
            t0 = time.perf_counter()
            for _ in range(n):
                publisher.put(payload)
            conn.send({"kind": "sent", "seconds": time.perf_counter() - t0})
    publisher.undeclare()
    pinger.undeclare()
    watch.undeclare()
    pongs.undeclare()


# ---------------------------------------------------------------------------- orchestration
@contextlib.contextmanager
def no_access_control() -> Iterator[None]:
    """Fleets started inside (and processes they spawn) run without authentication and access
    control (``ROCO_ACL=0``): the benchmark's own client sessions play agents (a_co, a_pl,
    a_ta) or synthetic agents the ACL does not know."""
    saved = {k: os.environ.get(k) for k in ("ROCO_ACL", "ROCO_SECURITY")}
    os.environ["ROCO_ACL"] = "0"
    os.environ.pop("ROCO_SECURITY", None)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@dataclass
class Child:
    """A process this benchmark started, and the parent's end of its pipe."""

    name: str
    process: BaseProcess
    conn: Connection

    def ask(self, cmd: tuple[Any, ...], timeout: float) -> Any:
        """Send ``cmd`` and wait up to ``timeout`` s for the child's answer; raises
        TimeoutError (naming the child) when none comes."""
        self.conn.send(cmd)
        return self.receive(timeout)

    def receive(self, timeout: float) -> Any:
        if not self.conn.poll(timeout):
            raise TimeoutError(f"{self.name} did not answer within {timeout:.0f} s")
        return self.conn.recv()


@dataclass
class Testbed:
    """A router on a free loopback port and the benchmark's child processes."""

    pairs: int
    children: dict[str, Child] = field(default_factory=dict)
    endpoint: str = ""
    fleet: Fleet | None = None
    start_s: float = 0.0
    """Wall time (s) from the first spawn until every child reported ready."""

    def start(self, agent_names: Sequence[str], raw_pairs: Sequence[int], timeout: float = 180.0) -> None:
        """Start the router, the agent processes ``agent_names`` and the raw echo/pinger
        processes for each pair in ``raw_pairs``; wait until every one reports ready."""
        run_dir = Path(tempfile.mkdtemp(prefix="roco-bench-"))
        (run_dir / "logs").mkdir()
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        with no_access_control():  # synthetic agents and bare sessions: no ACL knows them
            self.fleet = Fleet(run_dir, self.endpoint)
            self.fleet.start_router()
        ctx = mp.get_context("spawn")
        t0 = time.perf_counter()
        for name in agent_names:
            self._spawn(ctx, name, agent_process, (name, self.pairs, self.endpoint))
        for k in raw_pairs:
            for role in ("echo", "pinger"):
                self._spawn(ctx, f"raw_{role}{k}", raw_process, (role, k, self.endpoint))
        deadline = time.monotonic() + timeout
        for child in self.children.values():
            child.receive(max(1.0, deadline - time.monotonic()))
        self.start_s = time.perf_counter() - t0

    def _spawn(self, ctx: Any, name: str, target: Any, args: tuple[Any, ...]) -> None:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=target, args=(*args, child), name=name, daemon=True)
        proc.start()
        child.close()
        self.children[name] = Child(name, proc, parent)

    def rss_mib(self) -> dict[str, float]:
        """Resident memory (MiB, VmRSS of /proc/PID/status) of each child."""
        out = {}
        for name, c in self.children.items():
            if c.process.pid is not None:
                out[name] = process_rss_mib(c.process.pid)
        return out

    def stop(self) -> None:
        """Ask every child to stop, then end stragglers by PID; stop the router."""
        for c in self.children.values():
            with contextlib.suppress(OSError, ValueError):
                c.conn.send(("stop",))
        deadline = time.monotonic() + 10
        for c in self.children.values():
            c.process.join(max(0.1, deadline - time.monotonic()))
            if c.process.is_alive():
                c.process.kill()
                c.process.join(5)
            c.conn.close()
        if self.fleet is not None:
            self.fleet.stop()
            shutil.rmtree(self.fleet.run_dir, ignore_errors=True)


@contextlib.contextmanager
def testbed(pairs: int, agent_names: Sequence[str], raw_pairs: Sequence[int]) -> Iterator[Testbed]:
    """A started :class:`Testbed`, stopped on exit whatever happens."""
    bed = Testbed(pairs)
    try:
        bed.start(agent_names, raw_pairs)
        yield bed
    finally:
        bed.stop()


def process_rss_mib(pid: int) -> float:
    """VmRSS of process ``pid`` in MiB (0.0 when it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


@dataclass
class Latency:
    """Round-trip samples (s) and their percentiles (µs)."""

    samples_s: list[float]

    @property
    def p50_us(self) -> float:
        return percentile(self.samples_s, 50) * 1e6

    @property
    def p99_us(self) -> float:
        return percentile(self.samples_s, 99) * 1e6


@dataclass
class Throughput:
    """One-way throughput runs: delivered communicates, sent, time span (s) of each run."""

    runs: list[tuple[int, int, float]] = field(default_factory=list)

    @property
    def rates(self) -> list[float]:
        """Communicates per second of each run (count - 1 over first-to-last span)."""
        return [(c - 1) / s if s > 0 and c > 1 else 0.0 for c, _, s in self.runs]

    @property
    def median(self) -> float:
        return statistics.median(self.rates) if self.runs else 0.0

    @property
    def lost(self) -> int:
        return sum(max(0, sent - c) for c, sent, _ in self.runs)


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q``-th percentile (nearest rank) of ``values``; 0.0 when empty."""
    if not values:
        return 0.0
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))]


@dataclass
class PairFigures:
    """roco's and raw Zenoh's figures for one measured pair, pooled over the rounds."""

    roco_rt: Latency = field(default_factory=lambda: Latency([]))
    raw_rt: Latency = field(default_factory=lambda: Latency([]))
    roco_tput: Throughput = field(default_factory=Throughput)
    raw_tput: Throughput = field(default_factory=Throughput)


def _answer(child: Child, cmd: tuple[Any, ...], timeout: float) -> dict[str, Any]:
    out = child.ask(cmd, timeout)
    if not isinstance(out, dict) or "error" in out:
        raise RuntimeError(f"{child.name}: {out}")
    return out


def measure_pair(bed: Testbed, k: int, rounds: int, n_rt: int, n_tput: int, size: int) -> PairFigures:
    """Measure pair ``k`` (roco agents ``b_ini<k>``/``b_par<k>``, raw processes ``raw_*<k>``):
    ``rounds`` alternations of raw ping-pong, roco ping-pong, raw throughput and roco
    throughput, ``n_rt`` round trips and ``n_tput`` communicates each, ``size`` bytes of
    content (raw: payload of roco's encoded request's length)."""
    ini = bed.children[pair_names(k)[0]]
    echo, pinger = bed.children[f"raw_echo{k}"], bed.children[f"raw_pinger{k}"]
    raw_size = request_bytes(size)
    out = PairFigures()
    timeout = 120.0
    for _ in range(rounds):
        out.raw_rt.samples_s += _answer(pinger, ("pingpong", n_rt, raw_size), timeout)["samples_s"]
        out.roco_rt.samples_s += _answer(ini, ("pingpong", n_rt, size), timeout)["samples_s"]
        echo.ask(("arm", n_tput), timeout)
        _answer(pinger, ("send", n_tput, raw_size), timeout)
        got = echo.receive(timeout)
        out.raw_tput.runs.append((got["count"], n_tput, got["span_s"]))
        got = _answer(ini, ("stream", n_tput, size), timeout)
        out.roco_tput.runs.append((got["count"], n_tput, got["span_s"]))
    return out


@dataclass
class ConcurrentFigures:
    """All pairs doing round trips at once: pooled samples and the aggregate rate."""

    latency: Latency
    round_trips_per_s: float


def measure_all_pairs(bed: Testbed, pairs: int, n_rt: int, size: int) -> ConcurrentFigures:
    """Every pair's initiator does ``n_rt`` round trips at the same time (commands sent to all
    first, results gathered after); the aggregate rate is all round trips over the wall time
    from the first command to the last result."""
    inis = [bed.children[pair_names(k)[0]] for k in range(pairs)]
    t0 = time.perf_counter()
    for c in inis:
        c.conn.send(("pingpong", n_rt, size))
    samples: list[float] = []
    for c in inis:
        got = c.receive(300.0)
        if not isinstance(got, dict) or "samples_s" not in got:
            raise RuntimeError(f"{c.name}: {got}")
        samples += got["samples_s"]
    wall = time.perf_counter() - t0
    total = pairs * (n_rt + WARMUP)
    return ConcurrentFigures(Latency(samples), total / wall if wall > 0 else 0.0)


def messaging(rounds: int, n_rt: int, n_tput: int, size: int = 200) -> tuple[PairFigures, dict[str, float]]:
    """Part 2: one roco pair and one raw pair through one router; the figures and each
    process's resident memory (MiB) at the end."""
    names = pair_names(0)
    with testbed(1, names, [0]) as bed:
        figures = measure_pair(bed, 0, rounds, n_rt, n_tput, size)
        return figures, bed.rss_mib()


@dataclass
class ScaleRow:
    """Part 8 figures for ``agents`` synthetic agent processes sharing one router."""

    agents: int
    start_s: float
    rss_mib_total: float
    pair: PairFigures
    concurrent: ConcurrentFigures


def scale(
    agent_counts: Sequence[int], n_rt: int, n_tput: int, n_rt_all: int, size: int = 200
) -> list[ScaleRow]:
    """Part 8: for each N, N synthetic agents (N/2 pairs) and one raw pair on a fresh router;
    pair 0 measured (roco and raw) while the others are connected and idle; then every pair's
    round trips at once."""
    rows = []
    for n in agent_counts:
        pairs = max(1, n // 2)
        names = [name for k in range(pairs) for name in pair_names(k)]
        with testbed(pairs, names, [0]) as bed:
            pair = measure_pair(bed, 0, 1, n_rt, n_tput, size)
            concurrent = measure_all_pairs(bed, pairs, n_rt_all, size)
            rss = bed.rss_mib()
            agents_rss = sum(v for k, v in rss.items() if k.startswith("b_"))
            rows.append(ScaleRow(len(names), bed.start_s, agents_rss, pair, concurrent))
    return rows
