"""Messaging benchmark (``roco bench`` parts 2 and 8): roco's runtime against bare Zenoh on the
same link, measured side by side in the same run.

**roco**: two (or more) synthetic agents, each a real :class:`services.runtime.agent.Agent` in
its own process on a :class:`~services.runtime.transport.ZenohTransport` (explicit loopback
endpoint, no multicast scouting; linked as ``ROCO_LINKS`` says), started with
``multiprocessing`` *spawn*. They follow a small specification built here (:func:`bench_spec`:
one channel ``B<k>`` per pair, the real ``fipa-request`` and ``fipa-subscribe`` protocol
definitions of the Robot Companion's specification) and talk in a content language registered
here, ``L_BENCH`` (ontology O_RoCo), whose terms carry an opaque ``data`` field sized so that
the content of each communicate is the requested number of bytes. Every communicate goes
through the whole send and receive path: interface and protocol-state checks, content
encoding, the msgpack envelope (shared/fipa_codec), dedup digest, decoding, validation against
the interface and the content schema, the agent's input queue and FSM step.

- *round trip*: the initiator sends a ``request`` (fipa-request, a new conversation each time,
  ``expect_reply``) and the participant answers with an ``inform`` echoing the content; the
  time is taken (``time.perf_counter``) from the initiator's ``send`` call to the transition in
  which the inform is in its input buffer.
- *one-way throughput*: the initiator ``subscribe``s (fipa-subscribe) for ``n`` communicates;
  the participant ``agree``s and then sends ``n`` ``inform``s in the same conversation, 256
  per FSM step, either in one put per step (batched) or one put each; the initiator counts the
  informs that reach its input buffer, stamping each step of its behaviour that sees some, and
  divides those after the first such step by the time from it to the last (a step's informs
  all have that step's stamp).

**raw Zenoh**: two more Python processes with a bare session each, configured as an agent's
(:func:`~services.runtime.zenoh_config.member_config`: same router, links and, on a secure
testbed, credentials): a ping-pong (``put`` on a key, the other process takes it from a
subscriber's FIFO and ``put``s it back) and a throughput test (``put`` ``n`` payloads in a
loop; the other side's thread counts them from its FIFO). The payload has the size of roco's
encoded request communicate (envelope included), so the ratio is the runtime's cost.

Part 2 (:func:`messaging`) runs both on a :class:`Testbed` with access control and mutual TLS,
as every fleet runs, then on one without, and checks the roco pair's exchange through the
agents' counters (:func:`check_exchange`): a pair whose communicates are refused, not
understood or dropped by the access control fails the part (:class:`SetupError`).

The parent process only orchestrates (pipes to each child, no sleeps for synchronisation:
children report ``ready``, the initiators wait for their peer's liveliness token); every wait
has a timeout, and only the processes started here are ended, by their PID.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import shutil
import socket
import statistics
import sys
import tempfile
import time
import types
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

import msgspec

from services.bench.synthetic import (
    BENCH_LANGUAGE,
    COUNTERS,
    REACH,
    REACH_TIMEOUT_S,
    STALL_S,
    STREAM_BATCH,
    WARMUP,
    BenchInform,
    BenchInitiator,
    BenchParticipant,
    BenchRequest,
    BenchSubscription,
    _register,
    agent_process,
    bench_spec,
    pair_names,
    raw_process,
    request_bytes,
    sized_data,
)
from services.fleet.launcher import Fleet, free_port
from services.runtime.polling import max_poll_us
from services.runtime.zenoh_config import links_setting, one_hop
from shared.settings import Settings

__all__ = [
    "BENCH_LANGUAGE",
    "STALL_S",
    "STREAM_BATCH",
    "WARMUP",
    "BenchInform",
    "BenchInitiator",
    "BenchParticipant",
    "BenchRequest",
    "BenchSubscription",
    "_register",
    "bench_spec",
    "pair_names",
    "request_bytes",
    "sized_data",
]
"""The synthetic agents and their language live in services/bench/synthetic.py (the spawned
processes import only that); they are named here too for the callers of this module."""


# ---------------------------------------------------------------------------- orchestration
@contextlib.contextmanager
def no_access_control() -> Iterator[None]:
    """Fleets started inside (and processes they spawn) run without authentication and access
    control (``ROCO_ACL=0``): for benchmarks whose own client sessions play agents (a_co, a_pl,
    a_ta) the fleet's ACL does not let them be; part 2 measures both ways (:class:`Testbed`)."""
    acl, security = Settings.env_name("acl"), Settings.env_name("security")
    saved = {k: os.environ.get(k) for k in (acl, security)}
    os.environ[acl] = "0"
    os.environ.pop(security, None)
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
    """A router on a free loopback port and the benchmark's child processes; ``meshed``: a
    second router on another free port, meshed with the first (``--connect``), serving the
    participants and the raw echo while the initiators and the raw pinger stay on the first:
    every communicate crosses both routers and the link between them.

    ``secure``: access control and mutual TLS, as every fleet runs (services/fleet/launcher.py):
    credentials and the router's ACL issued by services/deploy/deploy.py ``prepare`` from
    :func:`bench_spec` (the raw pairs' identities included, services/bench/synthetic.py
    ``raw_names``), the router on ``tls/``, every process (agent or bare Zenoh)
    authenticating as itself with its certificate and password; else neither (``tcp/``, no
    credentials). Raises ValueError for ``secure`` with ``meshed``."""

    pairs: int
    meshed: bool = False
    secure: bool = False
    security: Path | None = None
    """The credentials folder of a ``secure`` testbed, once started."""
    children: dict[str, Child] = field(default_factory=dict)
    endpoint: str = ""
    endpoint2: str = ""
    """The second router's endpoint (``meshed``), else ""."""
    fleet: Fleet | None = None
    start_s: float = 0.0
    """Wall time (s) from the first spawn until every child reported ready."""
    reach_s: float | None = None
    """How long (s) :meth:`reach` waits for a pair's route (None: :data:`REACH_TIMEOUT_S`)."""

    def start(self, agent_names: Sequence[str], raw_pairs: Sequence[int], timeout: float = 180.0) -> None:
        """Start the router, the agent processes ``agent_names`` and the raw echo/pinger
        processes for each pair in ``raw_pairs``; wait until every one reports ready, then
        until every pair's route exists (:meth:`reach`). Raises TimeoutError or SetupError."""
        if self.secure and self.meshed:
            raise ValueError("a secure testbed has one router")
        run_dir = Path(tempfile.mkdtemp(prefix="roco-bench-"))
        (run_dir / "logs").mkdir()
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        if self.secure:
            from services.deploy.deploy import prepare  # cryptography: only where credentials are issued

            self.security = run_dir / "security"
            prepare(self.security, bench_spec(self.pairs, max(raw_pairs, default=-1) + 1), tls=True)
            # the fleet finds the folder prepared (deploy.ensure keeps it) and serves it on tls/
            self.fleet = Fleet(run_dir, self.endpoint, acl=True, tls=True)
            self.endpoint = self.fleet.endpoint
            self.fleet.start_router()
        else:
            self._start_open(run_dir, timeout)
        ctx = mp.get_context("spawn")
        t0 = time.perf_counter()
        security = None if self.security is None else str(self.security)
        for name in agent_names:
            args = (name, self.pairs, self._endpoint_of(name))
            self._spawn(ctx, name, agent_process, args, security)
        for k in raw_pairs:
            for role in ("echo", "pinger"):
                name = f"raw_{role}{k}"
                self._spawn(ctx, name, raw_process, (role, k, self._endpoint_of(name)), security)
        deadline = time.monotonic() + timeout
        for child in self.children.values():
            child.receive(max(1.0, deadline - time.monotonic()))
        self.start_s = time.perf_counter() - t0
        self.reach()

    def reach(self) -> None:
        """Make sure every pair's route exists before anything is timed
        (services/bench/synthetic.py :data:`REACH`): each roco initiator's request answered,
        each bare Zenoh publisher matched, within :attr:`reach_s`. Raises SetupError naming
        the ends that did not."""
        timeout = REACH_TIMEOUT_S if self.reach_s is None else self.reach_s
        ends = [c for name, c in self.children.items() if name.startswith(("b_ini", "raw_"))]
        for c in ends:
            c.conn.send((REACH, timeout))
        deadline = time.monotonic() + timeout
        wrong = [w for c in ends if (w := self._reached(c, deadline, timeout))]
        if wrong:
            raise SetupError("a pair's route was not there: " + "; ".join(wrong))

    def _reached(self, child: Child, deadline: float, timeout: float) -> str:
        """ "" when ``child`` answered :data:`REACH` by ``deadline`` (time.monotonic()), else
        ``"<name>: <why>"``."""
        try:
            got = child.receive(max(0.1, deadline - time.monotonic()))
        except TimeoutError:
            return f"{child.name}: {self._unreached(child, timeout)}"
        if isinstance(got, dict) and got.get("kind") == REACH:
            return ""
        return f"{child.name}: {got.get('error', got) if isinstance(got, dict) else got}"

    def _unreached(self, child: Child, timeout: float) -> str:
        """Why ``child`` did not answer :data:`REACH` within ``timeout`` s: for a roco initiator,
        its requests (retransmissions apart) and what its participant received of them."""
        if not child.name.startswith("b_ini"):
            return f"no answer within {timeout:g} s"
        name = "b_par" + child.name.removeprefix("b_ini")
        par = self.children.get(name)
        try:
            ini_n = counters_of(child)
            par_n = counters_of(par) if par is not None else None
        except TimeoutError as e:
            return f"no answer within {timeout:g} s, nor its counters ({e})"
        got = (
            f"received by {name} {par_n['received.request']}" if par_n is not None else f"{name} not started"
        )
        return (
            f"no answer within {timeout:g} s: requests sent {ini_n['sent.request']} (retransmitted "
            f"{ini_n['retransmitted']} times), {got}"
        )

    def _start_open(self, run_dir: Path, timeout: float) -> None:
        """The router (and the second one when ``meshed``) without access control."""
        with no_access_control():  # synthetic agents and bare sessions: no ACL knows them
            self.fleet = Fleet(run_dir, self.endpoint, acl=False, tls=False)
            self.fleet.start_router()
            if self.meshed:
                self.endpoint2 = f"tcp/127.0.0.1:{free_port()}"
                router = ["-m", "services.runtime.router", "--listen", self.endpoint2]
                self.fleet.start_service("router2", [*router, "--connect", self.endpoint])
                wait_listening(self.endpoint2, timeout)

    def _endpoint_of(self, name: str) -> str:
        """The router a child connects to: the second one for participants and the raw echo
        when ``meshed``."""
        if self.meshed and (name.startswith("b_par") or name.startswith("raw_echo")):
            return self.endpoint2
        return self.endpoint

    def _spawn(self, ctx: Any, name: str, target: Any, args: tuple[Any, ...], security: str | None) -> None:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=target, args=(*args, child, security), name=name, daemon=True)
        with _main_not_inherited():
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
def _main_not_inherited() -> Iterator[None]:
    """While a process is started with multiprocessing's spawn, hide this interpreter's
    ``__main__`` from it: spawn would otherwise import the parent's main module again in the
    child (``roco bench``'s: the whole CLI, typer included) before running its target, and the
    child's resident memory would be the CLI's rather than an agent's. The targets started here
    live in services/bench/synthetic.py, so the child needs nothing of ``__main__``."""
    saved = sys.modules["__main__"]
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        sys.modules["__main__"] = saved


def wait_listening(endpoint: str, timeout: float) -> None:
    """Return once a TCP connection to ``endpoint`` (``tcp/HOST:PORT``) is accepted; raises
    TimeoutError after ``timeout`` s."""
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host, int(port)), timeout=0.2):
                return
        except OSError:
            if time.monotonic() > deadline:
                raise TimeoutError(f"nothing listens on {endpoint} after {timeout:.0f} s") from None
            time.sleep(0.05)


@contextlib.contextmanager
def testbed(
    pairs: int,
    agent_names: Sequence[str],
    raw_pairs: Sequence[int],
    *,
    meshed: bool = False,
    secure: bool = False,
) -> Iterator[Testbed]:
    """A started :class:`Testbed`, stopped on exit whatever happens."""
    bed = Testbed(pairs, meshed, secure)
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


def process_pss_mib(pid: int) -> float:
    """Proportional set size of process ``pid`` in MiB (``Pss`` of ``/proc/<pid>/smaps_rollup``:
    its private pages plus each shared page divided by the processes mapping it, so that the
    sum over a fleet is the memory the fleet takes; 0.0 when it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
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
    """One-way throughput runs: delivered communicates, sent, time span (s) from the first
    stamp to the last, and the communicates counted at the first stamp, of each run."""

    runs: list[tuple[int, int, float, int]] = field(default_factory=list)

    def add(self, got: dict[str, Any], sent: int) -> None:
        """Keep one run's result (``count``, ``span_s``, ``first``) of ``sent`` communicates."""
        self.runs.append((int(got["count"]), sent, float(got["span_s"]), int(got.get("first", 1))))

    @property
    def rates(self) -> list[float]:
        """Communicates per second of each run: those counted after the first stamp over the
        span from it to the last (0 when the first stamp counted them all)."""
        return [(c - f) / s if s > 0 and c > f else 0.0 for c, _, s, f in self.runs]

    @property
    def median(self) -> float:
        return statistics.median(self.rates) if self.runs else 0.0

    @property
    def lost(self) -> int:
        return sum(max(0, sent - c) for c, sent, _, _ in self.runs)


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
    """Raw Zenoh's round trips, each end waiting in a blocking ``recv()`` (zenoh-python's own
    examples): the reference of the round-trip target (docs/benchmarks.md)."""
    raw_poll_rt: Latency = field(default_factory=lambda: Latency([]))
    """Raw Zenoh's round trips with each end polling as roco's receiving threads do
    (services/runtime/polling.py, the same maximum window): the ratio on equal terms."""
    poll_us: float = 0.0
    """The maximum poll window (µs) of roco's receiving threads in the run (0: off)."""
    roco_tput: Throughput = field(default_factory=Throughput)
    roco_tput_single: Throughput = field(default_factory=Throughput)
    """roco's stream with every communicate in a put of its own (``Engine.batch_puts`` False)."""
    raw_tput: Throughput = field(default_factory=Throughput)


class SetupError(RuntimeError):
    """The benchmark's pair did not do the work it is timed on: a communicate refused, not
    understood, dropped on the way (access control) or a round trip missing; the part fails
    instead of giving a figure."""


def _answer(child: Child, cmd: tuple[Any, ...], timeout: float) -> dict[str, Any]:
    out = child.ask(cmd, timeout)
    if not isinstance(out, dict) or "error" in out:
        raise SetupError(f"{child.name}: {out}")
    return out


def _samples(child: Child, cmd: tuple[Any, ...], timeout: float) -> list[float]:
    """The round trips (s) of a ``("pingpong", n, …)`` command; raises SetupError unless there
    are ``n``: the timed work is the work named."""
    samples: list[float] = _answer(child, cmd, timeout)["samples_s"]
    if len(samples) != cmd[1]:
        raise SetupError(f"{child.name} timed {len(samples)} round trips instead of {cmd[1]}")
    return samples


PROBE_S = 20.0
"""How long (s) the first exchange of a pair may take before the setup is called broken."""

UNWANTED = ("rejected", "protocol_violations", "send_violations", "content_violations", "bad_key")
"""Counters (services/runtime/counters.py) that must not move while a pair is measured, with
every ``rejected.<reason>`` and the not-understood, refuse and failure sent or received."""
_UNWANTED_ACTS = tuple(
    f"{way}.{act}" for way in ("sent", "received") for act in ("not-understood", "refuse", "failure")
)


def counters_of(child: Child, timeout: float = PROBE_S) -> Counter[str]:
    """A synthetic agent's counters (services/bench/synthetic.py ``COUNTERS``)."""
    got = _answer(child, (COUNTERS,), timeout)
    return Counter({str(k): int(v) for k, v in got["counters"].items()})


@dataclass(frozen=True)
class Exchange:
    """What one pair's initiator and participant should have sent each other, by performative."""

    by_initiator: dict[str, int]
    by_participant: dict[str, int]


def pair_exchange(rounds: int, n_rt: int, n_tput: int) -> Exchange:
    """What :func:`measure_pair` makes a roco pair send: per round ``WARMUP + n_rt`` requests
    answered by as many informs, and two subscribes (a batched stream, then one put per
    communicate), each agreed to and answered by ``n_tput`` informs."""
    rt = rounds * (WARMUP + n_rt)
    return Exchange(
        {"request": rt, "subscribe": 2 * rounds},
        {"inform": rt + 2 * rounds * n_tput, "agree": 2 * rounds},
    )


def check_exchange(
    ini: Mapping[str, int],
    par: Mapping[str, int],
    want: Exchange,
    names: tuple[str, str] = ("b_ini0", "b_par0"),
) -> None:
    """Check a pair's counter deltas (``ini``, ``par``: after minus before) against ``want``:
    each communicate sent by one end was received by the other (none dropped on the way: the
    access control drops silently), as many as ``want`` names, and nothing was refused, not
    understood, failed or rejected (:data:`UNWANTED`). Raises SetupError naming every
    difference."""
    wrong = [
        *_missing(names[0], ini, names[1], par, want.by_initiator),
        *_missing(names[1], par, names[0], ini, want.by_participant),
        *_unwanted(names[0], ini),
        *_unwanted(names[1], par),
    ]
    if wrong:
        raise SetupError("the pair's exchange was not the work timed: " + "; ".join(wrong))


def _missing(
    sender: str, sent: Mapping[str, int], receiver: str, got: Mapping[str, int], wanted: Mapping[str, int]
) -> list[str]:
    """Each performative of ``wanted`` that ``sender`` did not send, or ``receiver`` did not
    receive, exactly as often as wanted."""
    wrong = []
    for act, n in wanted.items():
        s, r = sent.get(f"sent.{act}", 0), got.get(f"received.{act}", 0)
        if s != n or r != n:
            wrong.append(f"{sender} sent {s} {act} and {receiver} received {r}, not {n}")
    return wrong


def _unwanted(name: str, deltas: Mapping[str, int]) -> list[str]:
    """``name``'s counters of :data:`UNWANTED` that moved, in one line (none: empty)."""
    bad = {
        k: v
        for k, v in deltas.items()
        if v and (k in UNWANTED or k.startswith("rejected.") or k in _UNWANTED_ACTS)
    }
    return [f"{name}: {', '.join(f'{k} {v}' for k, v in sorted(bad.items()))}"] if bad else []


def probe_pair(bed: Testbed, k: int, size: int) -> None:
    """Before pair ``k`` is timed: one warm-up's round trips of its roco pair and of its raw
    pair, each within :data:`PROBE_S`, and the roco pair's counters for them (nothing refused,
    not understood or dropped). Raises SetupError saying what went wrong."""
    ini, par = (bed.children[n] for n in pair_names(k))
    before = counters_of(ini), counters_of(par)
    try:
        _samples(ini, ("pingpong", 1, size), PROBE_S)
    except TimeoutError:
        after = counters_of(ini), counters_of(par)
        sent = after[0]["sent.request"] - before[0]["sent.request"]
        got = after[1]["received.request"] - before[1]["received.request"]
        raise SetupError(
            f"{ini.name} had no answer within {PROBE_S:.0f} s: requests sent {sent}, received by "
            f"{par.name} {got} (the rest dropped on the way: access control?)"
        ) from None
    after = counters_of(ini), counters_of(par)
    check_exchange(
        after[0] - before[0], after[1] - before[1], Exchange({"request": WARMUP + 1}, {"inform": WARMUP + 1})
    )
    try:
        _samples(bed.children[f"raw_pinger{k}"], ("pingpong", 1, request_bytes(size)), PROBE_S)
    except TimeoutError:
        raise SetupError(f"raw Zenoh pair {k} had no answer within {PROBE_S:.0f} s") from None


def measure_pair(bed: Testbed, k: int, rounds: int, n_rt: int, n_tput: int, size: int) -> PairFigures:
    """Measure pair ``k`` (roco agents ``b_ini<k>``/``b_par<k>``, raw processes ``raw_*<k>``):
    ``rounds`` alternations of raw ping-pong (blocking, then polling as roco's receiving
    threads do unless ``ROCO_RECEIVE_POLL_US`` is 0), roco ping-pong, raw throughput and roco
    throughput (in batches, then one put per communicate), ``n_rt`` round trips and ``n_tput``
    communicates each, ``size`` bytes of content (raw: payload of roco's encoded request's
    length)."""
    ini = bed.children[pair_names(k)[0]]
    echo, pinger = bed.children[f"raw_echo{k}"], bed.children[f"raw_pinger{k}"]
    raw_size = request_bytes(size)
    out = PairFigures(poll_us=max_poll_us())
    timeout = 120.0
    for _ in range(rounds):
        out.raw_rt.samples_s += _samples(pinger, ("pingpong", n_rt, raw_size), timeout)
        if out.poll_us > 0:
            echo.ask(("poll", out.poll_us), timeout)
            out.raw_poll_rt.samples_s += _samples(pinger, ("pingpong", n_rt, raw_size, out.poll_us), timeout)
            echo.ask(("poll", 0.0), timeout)
        out.roco_rt.samples_s += _samples(ini, ("pingpong", n_rt, size), timeout)
        echo.ask(("arm", n_tput), timeout)
        _answer(pinger, ("send", n_tput, raw_size), timeout)
        got = echo.receive(timeout)
        out.raw_tput.add(got, n_tput)
        got = _answer(ini, ("stream", n_tput, size), timeout)
        out.roco_tput.add(got, n_tput)
        got = _answer(ini, ("stream", n_tput, size, False), timeout)
        out.roco_tput_single.add(got, n_tput)
    return out


@dataclass
class ConcurrentFigures:
    """All pairs doing round trips at once: pooled samples and the aggregate rate."""

    latency: Latency
    round_trips_per_s: float
    """All round trips (warm-up included) over the wall time from the first command to the
    last result: includes the start, and the end when the last pairs finish alone."""
    steady_per_s: float = 0.0
    """Round trips that ended while every pair was doing its measured ones (from the latest
    first end to the earliest last end, CLOCK_MONOTONIC) over that window: the rate with all
    pairs at once, without the start and the tail; 0 when the window is empty."""
    steady_runs: list[float] = field(default_factory=list)
    """``steady_per_s`` of each run when the figures are the median of several
    (:func:`median_run`); empty for one run."""


def median_run(runs: Sequence[ConcurrentFigures]) -> ConcurrentFigures:
    """Several all-pairs runs as one: latency samples pooled, each rate the median of the
    runs' (the runs' steady rates kept in ``steady_runs``). Raises ValueError for no runs."""
    if not runs:
        raise ValueError("no all-pairs run to take the median of")
    return ConcurrentFigures(
        Latency([t for r in runs for t in r.latency.samples_s]),
        statistics.median(r.round_trips_per_s for r in runs),
        statistics.median(r.steady_per_s for r in runs),
        [r.steady_per_s for r in runs],
    )


def steady_rate(ends: Sequence[Sequence[float]]) -> float:
    """Round trips per second while every pair was running: ``ends`` holds each pair's end
    times (s, one clock); counted from the latest of the pairs' first ends to the earliest of
    their last ends. 0.0 when that window is empty (a pair finished before another began)."""
    if not ends or any(not e for e in ends):
        return 0.0
    start, stop = max(e[0] for e in ends), min(e[-1] for e in ends)
    if stop <= start:
        return 0.0
    inside = sum(1 for e in ends for t in e if start < t <= stop)
    return inside / (stop - start)


def measure_all_pairs(
    bed: Testbed, pairs: int, n_rt: int, size: int, *, raw: bool = False
) -> ConcurrentFigures:
    """Every pair's initiator does ``n_rt`` round trips at the same time (commands sent to all
    first, results gathered after); the aggregate rate is all round trips over the wall time
    from the first command to the last result. ``raw``: the raw Zenoh pingers of the testbed's
    raw pairs instead, each sleeping in ``recv()``, with a payload of roco's encoded request's
    length."""
    if raw:
        inis = [bed.children[f"raw_pinger{k}"] for k in range(pairs)]
        command: tuple[Any, ...] = ("pingpong", n_rt, request_bytes(size))
    else:
        inis = [bed.children[pair_names(k)[0]] for k in range(pairs)]
        command = ("pingpong", n_rt, size)
    t0 = time.perf_counter()
    for c in inis:
        c.conn.send(command)
    samples: list[float] = []
    ends: list[list[float]] = []
    for c in inis:
        got = c.receive(300.0)
        if not isinstance(got, dict) or "samples_s" not in got:
            raise RuntimeError(f"{c.name}: {got}")
        samples += got["samples_s"]
        ends.append(got.get("ends_s", []))
    wall = time.perf_counter() - t0
    total = pairs * (n_rt + WARMUP)
    return ConcurrentFigures(Latency(samples), total / wall if wall > 0 else 0.0, steady_rate(ends))


def checked_all_pairs(bed: Testbed, pairs: int, n_rt: int, size: int) -> ConcurrentFigures:
    """:func:`measure_all_pairs` of the roco pairs, each pair's exchange checked against what
    it was asked (:func:`check_exchange`: ``WARMUP + n_rt`` requests each answered, nothing
    refused, not understood or dropped). Raises SetupError when the work was not the work
    timed."""
    children = [tuple(bed.children[n] for n in pair_names(k)) for k in range(pairs)]
    before = [(counters_of(i), counters_of(p)) for i, p in children]
    figures = measure_all_pairs(bed, pairs, n_rt, size)
    want = Exchange({"request": WARMUP + n_rt}, {"inform": WARMUP + n_rt})
    for k, ((i, p), (bi, bp)) in enumerate(zip(children, before, strict=True)):
        check_exchange(counters_of(i) - bi, counters_of(p) - bp, want, pair_names(k))
    return figures


class MessagingSummary(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Part 2's headline figures (what a summary of the bench quotes): round trips' p50 (µs)
    and one pair's one-way stream (communicates/s, the median of the rounds), 200 B of content
    unless the run said otherwise. ``secure``: access control and mutual TLS on, as every
    fleet runs; ``open``: both off. Raw Zenoh is measured on the same link configuration as
    the roco figure it stands beside (same router, endpoint, credentials and hops)."""

    round_trip_p50_us: float
    """roco, access control and mutual TLS on."""
    raw_polling_p50_us: float
    """Raw Zenoh on the same link, each end polling as roco's receiving threads do (0: polling
    off, ``ROCO_RECEIVE_POLL_US=0``)."""
    raw_sleeping_p50_us: float
    """Raw Zenoh on the same link, each end sleeping in ``recv()``."""
    round_trip_open_p50_us: float
    """roco, access control and TLS off."""
    raw_polling_open_p50_us: float
    """Raw Zenoh polling, access control and TLS off."""
    stream_per_s: float
    """roco, one communicate per put, access control and mutual TLS on."""
    stream_batched_per_s: float
    """roco, the participant's 256 informs of a step in one put, access control and mutual TLS on."""
    stream_open_per_s: float
    """roco, one communicate per put, access control and TLS off."""
    raw_stream_per_s: float
    """Raw Zenoh, one payload per put, access control and mutual TLS on."""
    content_bytes: int
    links: str
    """How the pair's sessions reach each other: ``peer`` (one hop) or ``router`` (two)."""
    poll_us: float
    """The receiving threads' maximum poll window (µs; 0: off)."""

    @property
    def round_trip_ratio(self) -> float:
        """roco's round trip over raw Zenoh's polling on the same link (p50; inf when unmeasured)."""
        return self.round_trip_p50_us / self.raw_polling_p50_us if self.raw_polling_p50_us else float("inf")


@dataclass
class MessagingFigures:
    """Part 2: one roco pair and one raw pair measured on a testbed with access control and
    mutual TLS (``secure``, the headline) and on one without (``open``), each pair's exchange
    checked (:func:`check_exchange`); each process's resident memory (MiB) at the end of the
    open testbed's run."""

    secure: PairFigures
    open: PairFigures
    rss_mib: dict[str, float]
    size: int
    links: str
    """``peer`` or ``router``: the path the sessions took (``ROCO_LINKS`` and
    services/runtime/zenoh_config.py ``one_hop``; the same on both testbeds)."""

    @property
    def summary(self) -> MessagingSummary:
        s, o = self.secure, self.open
        return MessagingSummary(
            round_trip_p50_us=s.roco_rt.p50_us,
            raw_polling_p50_us=s.raw_poll_rt.p50_us,
            raw_sleeping_p50_us=s.raw_rt.p50_us,
            round_trip_open_p50_us=o.roco_rt.p50_us,
            raw_polling_open_p50_us=o.raw_poll_rt.p50_us,
            stream_per_s=s.roco_tput_single.median,
            stream_batched_per_s=s.roco_tput.median,
            stream_open_per_s=o.roco_tput_single.median,
            raw_stream_per_s=s.raw_tput.median,
            content_bytes=self.size,
            links=self.links,
            poll_us=s.poll_us,
        )


def checked_pair(bed: Testbed, rounds: int, n_rt: int, n_tput: int, size: int) -> PairFigures:
    """Pair 0 of ``bed`` probed (:func:`probe_pair`), measured (:func:`measure_pair`) and its
    exchange checked against what the measurement asked for (:func:`check_exchange`). Raises
    SetupError when the work was not the work timed."""
    probe_pair(bed, 0, size)
    ini, par = (bed.children[n] for n in pair_names(0))
    before = counters_of(ini), counters_of(par)
    figures = measure_pair(bed, 0, rounds, n_rt, n_tput, size)
    after = counters_of(ini), counters_of(par)
    check_exchange(after[0] - before[0], after[1] - before[1], pair_exchange(rounds, n_rt, n_tput))
    return figures


def path_of(bed: Testbed) -> str:
    """``peer`` when ``bed``'s sessions link to each other directly (one hop), else ``router``."""
    direct = links_setting() == "peer" and one_hop([bed.endpoint], bed.security)
    return "peer" if direct else "router"


def messaging(rounds: int, n_rt: int, n_tput: int, size: int = 200) -> MessagingFigures:
    """Part 2: one roco pair and one raw pair with access control and mutual TLS, then on a
    fresh testbed without (:class:`MessagingFigures`). Raises SetupError (:func:`checked_pair`)
    or TimeoutError (a process that does not answer)."""
    names = pair_names(0)
    with testbed(1, names, [0], secure=True) as bed:
        secure = checked_pair(bed, rounds, n_rt, n_tput, size)
        links = path_of(bed)
    with testbed(1, names, [0]) as bed:
        open_ = checked_pair(bed, rounds, n_rt, n_tput, size)
        rss = bed.rss_mib()
        if path_of(bed) != links:
            raise SetupError(f"the paths differ: {links} with access control, {path_of(bed)} without")
    return MessagingFigures(secure, open_, rss, size, links)


@dataclass
class ScaleRow:
    """Part 8 figures for ``agents`` synthetic agent processes sharing one router, or two
    meshed routers (``routers`` 2; :class:`Testbed`)."""

    agents: int
    start_s: float
    rss_mib_total: float
    pair: PairFigures
    concurrent: ConcurrentFigures
    routers: int = 1
    raw_concurrent: ConcurrentFigures | None = None
    """The same number of bare Zenoh processes (N/2 ping-pong pairs, no agent runtime) on a
    fresh router (or two), every pair at once: how the transport itself scales."""


def _scale_row(
    n: int, n_rt: int, n_tput: int, n_rt_all: int, size: int, meshed: bool, all_rounds: int
) -> ScaleRow:
    """:func:`scale`'s figures for ``n`` agents: pair 0 with the others idle, every pair at
    once, then as many bare Zenoh processes on a fresh testbed."""
    pairs = max(1, n // 2)
    names = [name for k in range(pairs) for name in pair_names(k)]
    with testbed(pairs, names, [0], meshed=meshed) as bed:
        pair = checked_pair(bed, 1, n_rt, n_tput, size)
        concurrent = median_run([checked_all_pairs(bed, pairs, n_rt_all, size) for _ in range(all_rounds)])
        rss = bed.rss_mib()
        agents_rss = sum(v for k, v in rss.items() if k.startswith("b_"))
        start_s = bed.start_s
    with testbed(pairs, [], range(pairs), meshed=meshed) as bed:
        raw = median_run([measure_all_pairs(bed, pairs, n_rt_all, size, raw=True) for _ in range(all_rounds)])
    return ScaleRow(len(names), start_s, agents_rss, pair, concurrent, 2 if meshed else 1, raw)


def scale(
    agent_counts: Sequence[int],
    n_rt: int,
    n_tput: int,
    n_rt_all: int,
    size: int = 200,
    *,
    meshed: bool = False,
    all_rounds: int = 1,
    before: Callable[[str], None] | None = None,
) -> list[ScaleRow]:
    """Part 8: for each N, N synthetic agents (N/2 pairs) and one raw pair on a fresh router
    (``meshed``: two meshed routers, each pair split across them; :class:`Testbed`); pair 0
    measured (roco and raw) while the others are connected and idle; then every pair's round
    trips at once, ``all_rounds`` times (the median run: :func:`median_run`); then, on a fresh
    testbed, N bare Zenoh processes (N/2 raw pairs) doing their round trips at once, as many
    times. ``before`` is called with each N's label before its testbed starts (``roco bench``
    waits there for a quiet machine)."""
    rows = []
    for n in agent_counts:
        if before is not None:
            agents = 2 * max(1, n // 2)
            before(f"before scale, {agents} agents{', two routers' if meshed else ''}")
        rows.append(_scale_row(n, n_rt, n_tput, n_rt_all, size, meshed, all_rounds))
    return rows
