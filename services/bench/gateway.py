"""Part 9 of ``roco bench``: the ACL gateway (``roco gateway``) under load and under attack.

A router with access control and ``roco gateway`` as a process of that fleet (no agents: what
it forwards is put on Zenoh and goes nowhere); in this process, peers on asyncio streams post
messages as JADE 4.6 writes them (FIPA SC00084 body, SC00085 envelope, SC00070 payload), each
peer a foreign agent of its own, and an HTTP inbox (:class:`Inbox`) takes the answers posted
back. Three measurements:

- **load**: ``peers`` peers at once, each posting ``messages`` requests one after the other (a
  sentence to a_hi, a conversation each): accepted messages per second (answers 200 over the
  wall time from the first connection to the last answer) and the latency of one post
  (connect → status line), p50 and p99;
- **burst**: ``peers`` peers connect and post one request each at the same moment: how many
  are answered, with which statuses, and when the last answer came (from the start);
- **worst bodies** (:func:`worst_requests`): each alone, then the three heaviest at once
  (:data:`TOGETHER`), each time followed by a valid message that the gateway answers (a
  request to a_co, refused and posted to the inbox): the status, the gateway's
  peak RSS over its RSS before (``VmHWM`` reset through ``/proc/PID/clear_refs``) and its CPU
  time, user and system (``/proc/PID/stat``), from the post until that answer arrived.

Between the burst and the worst bodies, the legitimate traffic is checked
(services/bench/gateway_check.py): every request answered 200, counted received and forwarded
by the gateway, none refused, each taken on a_hi's side of the router; else the part raises
SetupRefused and prints no figure.

The test suite runs the worst bodies with bounds (tests/gateway/test_worst_bodies.py); the
figures here are the benchmark's.
"""

from __future__ import annotations

import asyncio
import json
import os
import queue
import shutil
import socket
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from threading import Thread

from services.bench.messaging import percentile
from services.fleet.launcher import Fleet

__all__ = [
    "BurstFigures",
    "GatewayFigures",
    "GatewayProcess",
    "Inbox",
    "LoadFigures",
    "WorstRow",
    "body",
    "measure",
    "request",
    "worst_requests",
]

BOUNDARY = "a36869921a26b9d812878b42b8fc2cd"
MIB = 1024 * 1024
BODY_LIMIT = 8 * MIB
"""The gateway's largest body (services/gateway/bounds.py ``max_body``): the worst bodies fill it."""


# ---------------------------------------------------------------------------- what peers send
def acl(sender: str, to: str, content: str, conversation: str, addresses: str = "") -> str:
    """A request in the string form as JADE's ``ACLMessage.toString`` prints it."""
    quoted = content.replace('"', '\\"')
    where = f" :addresses (sequence {addresses})" if addresses else ""
    return (
        f"(REQUEST :sender (agent-identifier :name {sender}{where}) "
        f':receiver (set (agent-identifier :name {to})) :content "{quoted}" '
        f":language L_HC :ontology O_RoCo :protocol fipa-request "
        f":conversation-id {conversation} :reply-with {conversation}-r1)"
    )


def envelope(to: str, sender: str, payload_length: int | str, *, encoding: str = "US-ASCII") -> str:
    """An XML envelope (FIPA SC00085) as JADE's ``XMLCodec`` writes it."""
    return (
        '<?xml version="1.0"?>\n<envelope><params index="1">'
        f"<to><agent-identifier><name>{to}</name></agent-identifier></to>"
        f"<from><agent-identifier><name>{sender}</name></agent-identifier></from>"
        "<acl-representation>fipa.acl.rep.string.std</acl-representation>"
        f"<payload-length>{payload_length}</payload-length>"
        f"<payload-encoding>{encoding}</payload-encoding><date>20261122T201900000Z</date>"
        "</params></envelope>"
    )


def body(xml: str | bytes, payload: bytes, *, payload_headers: str = "") -> bytes:
    """The multipart body JADE's ``HTTPIO`` writes (preamble, envelope part, payload part)."""
    b = BOUNDARY.encode()
    xml_bytes = xml.encode() if isinstance(xml, str) else xml
    extra = payload_headers.encode()
    return b"".join(
        [
            b"This is not part of the MIME multipart encoded message.\r\n",
            b"--" + b + b"\r\nContent-Type: application/xml\r\n\r\n",
            xml_bytes + b"\r\n",
            b"--" + b + b"\r\nContent-Type: fipa.acl.rep.string.std; charset=US-ASCII\r\n" + extra + b"\r\n",
            payload + b"\r\n",
            b"--" + b + b"--\r\n",
        ]
    )


def request(
    url: str, data: bytes, *, content_type: str | None = None, length: str | None = None, headers: str = ""
) -> bytes:
    """A whole POST of ``data`` to ``url`` with JADE's headers (the whole URL as target);
    ``length`` replaces the Content-Length value, ``headers`` adds header lines."""
    host = url.split("//", 1)[1].split("/", 1)[0]
    kind = content_type or f'multipart/mixed ; boundary="{BOUNDARY}"'
    head = (
        f"POST {url} HTTP/1.1\r\nCache-Control: no-cache\r\nMime-Version: 1.0\r\nHost: {host}\r\n"
        f"Content-Type: {kind}\r\nContent-Length: {length or len(data)}\r\n{headers}Connection: close\r\n\r\n"
    )
    return head.encode("latin-1") + data


def sentence_content(text: str) -> str:
    """The content (JSON of an L_HC sentence) of a request carrying ``text``."""
    return json.dumps({"type": "sentence", "text": text})


def message(
    url: str, sender: str, to: str, text: str, conversation: str, answer_at: str, content: str | None = None
) -> bytes:
    """A whole POST of a request from ``sender`` to ``to`` carrying the sentence ``text`` (or
    ``content`` as it is, when given)."""
    said = sentence_content(text) if content is None else content
    payload = acl(sender, to, said, conversation, answer_at).encode()
    return request(url, body(envelope(to, sender, len(payload)), payload))


def worst_requests(url: str, answer_at: str) -> dict[str, tuple[bytes, int]]:
    """What a hostile peer sends, as whole requests to the gateway at ``url``: name → (request,
    the status the gateway answers). Bodies fill the 8 MiB limit where size is the attack.
    ``answer_at`` is where the attacker's answers would go."""
    sender = "mallory@evil:1099/JADE"
    ok_env = envelope("a_hi", sender, 0)
    room = BODY_LIMIT - 1024

    def with_payload(payload: bytes, xml: str = ok_env, **kw: str) -> bytes:
        return request(url, body(xml, payload, **kw))

    def sentence(content: str, to: str = "a_hi", addresses: str = answer_at, who: str = sender) -> bytes:
        return acl(who, to, content, "c-worst", addresses).encode()

    laughs = (
        '<?xml version="1.0"?><!DOCTYPE envelope ['
        + '<!ENTITY a0 "ha">'
        + "".join(f'<!ENTITY a{i} "{f"&a{i - 1};" * 10}">' for i in range(1, 10))
        + "]><envelope><params><comments>&a9;</comments></params></envelope>"
    )
    nested_xml = "<envelope>" + "<a>" * 6000 + "</a>" * 6000 + "</envelope>"
    deep_json = "[" * 30_000 + "]" * 30_000
    return {
        "payload: 8 MiB of '('": (with_payload(b"(" * room), 406),
        "payload: 4 Mi tokens (one expression)": (
            with_payload(b"(request :X-a (" + b"a " * (room // 2) + b"))"),
            406,
        ),
        "payload: 100,000 answer addresses": (
            with_payload(sentence("x", addresses=" ".join(f"http://h{i}:1/acc" for i in range(100_000)))),
            406,
        ),
        "payload: 7 MiB string of escaped quotes": (with_payload(sentence('"' * (room // 2 - 512))), 200),
        "payload: JSON nested 30,000 deep": (with_payload(sentence(deep_json)), 200),
        "payload-encoding: punycode, 1 MiB": (
            with_payload(b"\xff" * MIB, envelope("a_hi", sender, MIB, encoding="punycode")),
            406,
        ),
        "body: 8 MiB of newlines": (request(url, b"\n" * room), 406),
        "body: 8 MiB of boundary lines": (request(url, f"--{BOUNDARY}\r\n".encode() * (room // 36)), 406),
        "body: Content-Transfer-Encoding x-uuencode": (
            with_payload(sentence("x"), payload_headers="Content-Transfer-Encoding: x-uuencode\r\n"),
            406,
        ),
        "envelope: entity definitions (billion laughs)": (with_payload(sentence("x"), laughs), 406),
        "envelope: 6,000 nested elements": (with_payload(sentence("x"), nested_xml), 406),
        "envelope: payload-length of 5,000 digits": (
            with_payload(sentence("x"), envelope("a_hi", sender, "9" * 5000)),
            406,
        ),
        "Content-Length of 5,000 digits": (request(url, b"x", length="9" * 5000), 400),
        "headers: 100 fields": (request(url, b"x", headers="X-a: b\r\n" * 100), 431),
        "sender: a roco agent's name": (with_payload(sentence("x", who="a_co")), 403),
        "answer address: the gateway's own": (
            with_payload(
                sentence("x", to="a_co", addresses=url, who="loop@evil:1099/JADE"),
                envelope("a_co", "loop@evil:1099/JADE", 0),
            ),
            200,
        ),
    }


async def post(address: tuple[str, int], data: bytes, timeout: float = 60.0) -> int:
    """Send a whole request on a new connection; the answer's status (0: none, the connection
    closed or reset)."""
    try:
        async with asyncio.timeout(timeout):
            reader, writer = await asyncio.open_connection(*address)
            try:
                writer.write(data)
                await writer.drain()
                line = await reader.readline()
            finally:
                writer.close()
    except (OSError, TimeoutError):
        return 0
    parts = line.split()
    return int(parts[1]) if len(parts) >= 2 and parts[1].isdigit() else 0


def post_now(address: tuple[str, int], data: bytes, timeout: float = 60.0) -> int:
    """:func:`post` from a thread without an event loop."""
    return asyncio.run(post(address, data, timeout))


# ---------------------------------------------------------------------------- who answers back
class Inbox:
    """An HTTP server on 127.0.0.1 taking every POST (200) and queueing its Content-Type and
    body: the foreign platform the gateway answers."""

    def __init__(self) -> None:
        self.bodies: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()
        inbox = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def log_message(self, format: str, *args: object) -> None:
                pass

            def do_POST(self) -> None:
                data = self.rfile.read(int(self.headers.get("Content-Length", "0")))
                inbox.bodies.put((self.headers.get("Content-Type", ""), data))
                self.send_response(200)
                self.send_header("Content-Length", "0")
                self.send_header("Connection", "close")
                self.end_headers()

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.address = f"http://127.0.0.1:{self.server.server_address[1]}/acc"
        Thread(target=self.server.serve_forever, args=(0.05,), daemon=True).start()

    def next(self, timeout: float = 30.0) -> tuple[str, bytes]:
        """The next post's Content-Type and body; queue.Empty after ``timeout`` s."""
        return self.bodies.get(timeout=timeout)

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


# ---------------------------------------------------------------------------- the gateway
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class GatewayProcess:
    """``roco gateway`` as a process of a fleet with access control (:meth:`start`)."""

    fleet: Fleet
    pid: int
    url: str
    address: tuple[str, int]
    endpoint: str

    @classmethod
    def start(cls, run_dir: Path, *, acl: bool = True, timeout: float = 60.0) -> GatewayProcess:
        """A router (with access control when ``acl``) and ``roco gateway`` in ``run_dir``,
        serving once this returns. Raises RuntimeError when it does not serve in time."""
        (run_dir / "logs").mkdir(parents=True, exist_ok=True)
        fleet = Fleet(run_dir, f"tcp/127.0.0.1:{_free_port()}", acl=acl)
        fleet.start_router()
        port = _free_port()
        fleet.start_service(
            "gateway", ["-m", "services.cli", "gateway", "--router", fleet.endpoint, "--port", str(port)]
        )
        gateway = cls(
            fleet,
            fleet.processes["gateway"].pid,
            f"http://127.0.0.1:{port}/acc",
            ("127.0.0.1", port),
            fleet.endpoint,
        )
        deadline = time.monotonic() + timeout
        while b"roco gateway: http://" not in gateway.log():
            if fleet.processes["gateway"].poll() is not None or time.monotonic() > deadline:
                gateway.stop()
                raise RuntimeError(
                    f"roco gateway did not start: {gateway.log()[-500:].decode(errors='replace')}"
                )
            time.sleep(0.05)
        return gateway

    def log(self) -> bytes:
        """What the gateway wrote (stdout and stderr)."""
        path = self.fleet.run_dir / "logs" / "gateway.stderr"
        return path.read_bytes() if path.exists() else b""

    def status(self) -> dict[str, int]:
        """VmRSS, VmHWM (kB) and threads of the process (``/proc/PID/status``)."""
        out: dict[str, int] = {}
        for line in Path(f"/proc/{self.pid}/status").read_text().splitlines():
            name, _, value = line.partition(":")
            if name in ("VmRSS", "VmHWM", "Threads"):
                out[name] = int(value.split()[0])
        return out

    def reset_peak(self) -> None:
        """Reset the process's peak RSS (``VmHWM``) to its RSS now (Linux ``clear_refs`` 5)."""
        Path(f"/proc/{self.pid}/clear_refs").write_text("5")

    def cpu_s(self) -> float:
        """CPU time used so far, user and system (s)."""
        fields = Path(f"/proc/{self.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def counters(self, timeout: float = 5.0) -> dict[str, int]:
        """The gateway's counters, asked over Zenoh as ``roco status`` asks them."""
        from services.runtime.counters import ask_counters
        from services.runtime.session import open_client

        session = open_client(self.endpoint)
        try:
            reports = ask_counters(session, {"gateway"}, timeout=timeout)
        finally:
            session.close()
        return dict(reports["gateway"].counters) if "gateway" in reports else {}

    def stop(self) -> None:
        self.fleet.stop()


# ---------------------------------------------------------------------------- measurements
@dataclass(frozen=True)
class LoadFigures:
    """Many peers posting at once: ``peers`` × ``messages`` requests; ``accepted`` answered
    200, at ``per_s`` a second; latency of one post (ms)."""

    peers: int
    messages: int
    accepted: int
    per_s: float
    p50_ms: float
    p99_ms: float
    statuses: dict[int, int]


@dataclass(frozen=True)
class BurstFigures:
    """``peers`` posting one request each at the same moment: ``answered`` 200 of them, the
    last answer ``last_s`` after the start."""

    peers: int
    answered: int
    last_s: float
    statuses: dict[int, int]


@dataclass(frozen=True)
class WorstRow:
    """One worst request, or ``requests`` of them at once: the status (expected, got; the
    highest of them), the gateway's peak RSS over its RSS before (MiB) and its CPU time until
    the next valid message was answered (s)."""

    name: str
    expected: int
    status: int
    rss_growth_mib: float
    cpu_s: float
    requests: int = 1


@dataclass
class GatewayFigures:
    """What part 9 measured."""

    load: LoadFigures
    burst: BurstFigures
    worst: list[WorstRow]
    rss_mib: float
    peak_mib: float
    counters: dict[str, int] = field(default_factory=dict)


def _conversation(peer: int, i: int) -> str:
    return f"c{peer}-{i}"


def _peer_messages(url: str, peer: int, n: int, content: str | None = None) -> Iterator[bytes]:
    name = f"peer{peer}@bench:1099/JADE"
    for i in range(n):
        yield message(
            url, name, "a_hi", "bring me the cup", _conversation(peer, i), "http://127.0.0.1:9/acc", content
        )


BURST_PEER = 10_000
"""The first burst peer's number (load peers are numbered from 0)."""


async def _load(
    url: str, address: tuple[str, int], peers: int, messages: int, content: str | None = None
) -> LoadFigures:
    latencies: list[float] = []
    statuses: Counter[int] = Counter()

    async def peer(i: int) -> None:
        for data in _peer_messages(url, i, messages, content):
            t = time.perf_counter()
            status = await post(address, data)
            latencies.append(time.perf_counter() - t)
            statuses[status] += 1

    t0 = time.perf_counter()
    await asyncio.gather(*(peer(i) for i in range(peers)))
    wall = time.perf_counter() - t0
    ms = [x * 1000 for x in latencies]
    return LoadFigures(
        peers,
        messages,
        statuses[200],
        statuses[200] / wall,
        percentile(ms, 50),
        percentile(ms, 99),
        dict(statuses),
    )


async def _burst(url: str, address: tuple[str, int], peers: int, content: str | None = None) -> BurstFigures:
    data = [next(_peer_messages(url, BURST_PEER + i, 1, content)) for i in range(peers)]
    done: list[float] = []
    t0 = time.perf_counter()

    async def one(d: bytes) -> int:
        status = await post(address, d)
        done.append(time.perf_counter() - t0)
        return status

    statuses = Counter(await asyncio.gather(*(one(d) for d in data)))
    return BurstFigures(peers, statuses[200], max(done), dict(statuses))


TOGETHER = (
    "payload: 8 MiB of '('",
    "payload: 4 Mi tokens (one expression)",
    "payload: 7 MiB string of escaped quotes",
)
"""The worst requests also sent at the same moment, on three connections."""


def worst(gateway: GatewayProcess, inbox: Inbox) -> list[WorstRow]:
    """Each of :func:`worst_requests` alone, then :data:`TOGETHER` at once, each followed by a
    valid message the gateway answers (module docstring); the last row's status is the worst
    of the three."""
    rows = []
    attacks = worst_requests(gateway.url, "http://127.0.0.1:9/acc")
    batches = [(name, [attack]) for name, attack in attacks.items()]
    batches.append((f"{len(TOGETHER)} at once: " + ", ".join(TOGETHER), [attacks[n] for n in TOGETHER]))

    async def at_once(requests: list[bytes]) -> list[int]:
        return await asyncio.gather(*(post(gateway.address, r) for r in requests))

    for follow, (name, batch) in enumerate(batches):
        gateway.reset_peak()
        before_rss, before_cpu = gateway.status()["VmRSS"], gateway.cpu_s()
        statuses = asyncio.run(at_once([data for data, _ in batch]))
        valid = message(
            gateway.url, "da0@bench:1099/JADE", "a_co", "bring me the cup", f"f{follow}", inbox.address
        )
        post_now(gateway.address, valid)
        inbox.next()
        cpu = gateway.cpu_s() - before_cpu
        expected = max(e for _, e in batch)
        growth = (gateway.status()["VmHWM"] - before_rss) / 1024
        rows.append(WorstRow(name, expected, max(statuses), growth, cpu, len(batch)))
    return rows


def measure(
    quick: bool = False, load_peers: int = 100, burst_peers: int = 500, content: str | None = None
) -> GatewayFigures:
    """Part 9 (module docstring): load with ``load_peers`` peers (20 messages each; 2 with
    ``quick``), a burst of ``burst_peers`` (50 with ``quick``), the worst bodies. The gateway's
    run folder (its router, credentials and logs) is removed at the end. ``content``: the
    legitimate requests' content in place of the sentence (a planted fault).

    Raises SetupRefused (services/bench/gateway_check.py) before the worst bodies when any
    legitimate request of the load or the burst was not answered 200, was refused by the
    gateway or did not reach a_hi's side of the router."""
    from services.bench.gateway_check import Receptor, check_legitimate
    from services.runtime.session import open_client

    run_dir = Path(tempfile.mkdtemp(prefix="roco-bench-gateway-"))
    gateway = GatewayProcess.start(run_dir)
    inbox = Inbox()
    session = open_client(gateway.endpoint)
    try:
        receptor = Receptor(session)
        messages, burst_n = (2 if quick else 20), (50 if quick else burst_peers)
        load = asyncio.run(_load(gateway.url, gateway.address, load_peers, messages, content))
        burst = asyncio.run(_burst(gateway.url, gateway.address, burst_n, content))
        sent = [_conversation(p, i) for p in range(load_peers) for i in range(messages)]
        sent += [_conversation(BURST_PEER + p, 0) for p in range(burst_n)]
        statuses = Counter(load.statuses) + Counter(burst.statuses)
        check_legitimate(statuses, gateway.counters(), sent, receptor)
        receptor.close()
        rss = gateway.status()["VmRSS"] / 1024
        rows = worst(gateway, inbox)
        peak = max(r.rss_growth_mib for r in rows) + rss
        counters = gateway.counters()
    finally:
        session.close()
        inbox.close()
        gateway.stop()
        shutil.rmtree(run_dir, ignore_errors=True)
    return GatewayFigures(load, burst, rows, rss, peak, counters)
