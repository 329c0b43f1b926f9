"""Several threads putting communicates on one key: with the backlog (services/runtime/backlog.py)
and with every communicate in a put of its own.

A router and the sending :class:`ZenohTransport` in this process, the receiver (a
``ZenohTransport`` subscribed to the inbox as an agent is, counting communicates with batches
split) in a process of its own (spawn), loopback TCP. ``--threads`` threads each publish
``--n`` encoded informs of 200 B content on the one key ``roco/fipa/C4/a_km/a_pl``, as fast as
they can. Figures per run: communicates a second (all sent, from the threads' start to the
receiver's last arrival, ``time.perf_counter``, one clock on Linux for both processes), and
communicates per Zenoh sample (``backlog`` > 1: batches formed). The two variants take turns
``--repeats`` times; without the backlog each ``publish`` puts directly
(``ZenohTransport._backlog`` replaced by a pass-through). First, the cost of one ``publish``
alone (the common path): ``--n`` in a loop on one thread, the fastest of 7 each way.

Usage: ``python scripts/bench_backlog.py [--threads 1,2,4] [--n 20000] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import statistics
import sys
import threading
import time
from multiprocessing.connection import Connection
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from services.fleet.launcher import free_port  # noqa: E402
from services.runtime import keys  # noqa: E402
from services.runtime.transport import ZenohTransport  # noqa: E402
from services.runtime.zenoh_config import router_config  # noqa: E402
from shared.fipa_codec import Performative, encode  # noqa: E402
from shared.fipa_codec.batch import unpack  # noqa: E402
from tests.support.messages import communicate  # noqa: E402

KEY = keys.fipa_key("C4", "a_km", "a_pl")
HELLO = b"hello"


class Direct:
    """A stand-in for the backlog: every publish is its own put."""

    def __init__(self, transport: ZenohTransport) -> None:
        self._put_on = transport._put_on
        self.joined = 0

    def publish(self, key: str, payload: bytes) -> None:
        self._put_on(key)(payload)


def receive(endpoint: str, conn: Connection) -> None:
    """The receiver: answer ``hello`` when it comes; per run (``total`` sent by the parent),
    count communicates and samples and report the time of the last arrival."""
    transport = ZenohTransport([endpoint])
    lock = threading.Lock()
    state = {"want": 0, "got": 0, "samples": 0, "last": 0.0}

    def report_if_done() -> None:  # lock held
        if state["want"] and state["got"] >= state["want"]:
            conn.send(("done", state["last"], state["got"], state["samples"]))
            state.update(want=0, got=0, samples=0)

    def arrived(_key: str, payload: bytes) -> None:
        if payload == HELLO:
            conn.send(("hello",))
            return
        n = len(unpack(payload))
        with lock:
            state["got"] += n
            state["samples"] += 1
            state["last"] = time.perf_counter()
            report_if_done()

    transport.subscribe(keys.inbox_key("a_pl"), arrived)
    conn.send(("ready",))
    while True:
        cmd = conn.recv()
        if cmd[0] == "stop":
            break
        with lock:
            state["want"] = cmd[1]
            report_if_done()
    transport.close()


def run_once(
    sender: ZenohTransport, conn: Connection, threads: int, n: int, payloads: list[bytes]
) -> tuple[float, float]:
    """(communicates /s, communicates per sample) of one run."""
    conn.send(("want", threads * n))
    start = threading.Barrier(threads + 1)

    def produce() -> None:
        start.wait()
        for p in payloads:
            sender.publish(KEY, p)

    workers = [threading.Thread(target=produce) for _ in range(threads)]
    for w in workers:
        w.start()
    start.wait()
    t0 = time.perf_counter()
    for w in workers:
        w.join()
    if not conn.poll(60.0):
        raise RuntimeError("the receiver did not get every communicate within 60 s")
    _, t_end, got, samples = conn.recv()
    return got / (t_end - t0), got / samples


def publish_cost(sender: ZenohTransport, payload: bytes, n: int) -> float:
    """Seconds a ``publish`` of ``payload`` takes, over ``n`` in a loop on this thread."""
    t0 = time.perf_counter()
    for _ in range(n):
        sender.publish(KEY, payload)
    return (time.perf_counter() - t0) / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", default="1,2,4")
    ap.add_argument("--n", type=int, default=20000, help="communicates each thread puts")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    import zenoh

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(router_config([endpoint]))
    parent, child = mp.get_context("spawn").Pipe()
    proc = mp.get_context("spawn").Process(target=receive, args=(endpoint, child), daemon=True)
    proc.start()
    assert parent.recv()[0] == "ready"
    sender = ZenohTransport([endpoint])
    while not parent.poll(0.05):  # the route is there once the receiver answers hello
        sender.publish(KEY, HELLO)
    while parent.poll(0.2):
        parent.recv()
    payloads = [
        encode(communicate(Performative.INFORM, "a_km", "a_pl", None, f"c{i}", content=b"x" * 200))
        for i in range(args.n)
    ]
    backlog, direct = sender._backlog, Direct(sender)
    try:
        cost = {"backlog": 1.0, "direct": 1.0}
        for _ in range(7):  # one publish alone, no thread else: the common path's cost
            for name, via in (("backlog", backlog), ("direct", direct)):
                sender._backlog = via  # type: ignore[assignment]
                cost[name] = min(cost[name], publish_cost(sender, payloads[0], args.n))
        parent.send(("want", 14 * args.n))  # what those put is counted, then let go
        assert parent.poll(60.0)
        parent.recv()
        print(
            f"one publish: {cost['backlog'] * 1e6:.2f} µs with the backlog, "
            f"{cost['direct'] * 1e6:.2f} µs without"
        )
        for threads in (int(t) for t in args.threads.split(",")):
            figures: dict[str, list[tuple[float, float]]] = {"backlog": [], "direct": []}
            for _ in range(args.repeats):
                for name, via in (("backlog", backlog), ("direct", direct)):
                    sender._backlog = via  # type: ignore[assignment]
                    figures[name].append(run_once(sender, parent, threads, args.n, payloads))
            for name, runs in figures.items():
                rates = sorted(r for r, _ in runs)
                per = statistics.median(p for _, p in runs)
                print(
                    f"{threads} thread(s), {name:7}: {statistics.median(rates):9,.0f} /s "
                    f"(runs {', '.join(f'{r:,.0f}' for r in rates)}), {per:.1f} communicates a sample"
                )
    finally:
        sender._backlog = backlog
        parent.send(("stop",))
        proc.join(10.0)
        sender.close()
        router.close()


if __name__ == "__main__":
    main()
