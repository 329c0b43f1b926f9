"""Where a roco round trip spends its time, at the level of threads and wake-ups
(docs/benchmarks.md, "The path of one communicate").

A router on a free loopback port (no access control, no multicast scouting) and, each in its own
process (multiprocessing spawn), the benchmark's synthetic pair ``b_ini0``/``b_par0``
(services/bench/synthetic.py) and a bare-Zenoh echo pair, as ``roco bench`` runs them. In the
two agent processes the runtime is traced (``time.perf_counter_ns``, CLOCK_MONOTONIC: one clock
for every process of the host; the thread's native id) at five points of each communicate:

- ``send``: :meth:`Engine.send` or :meth:`Engine.reply` called (by the behaviour's transition function);
- ``put``: :meth:`ZenohTransport.publish` called (the output buffer dispatched after the step);
- ``cb``: Zenoh's subscriber callback entered (on a Zenoh thread);
- ``take0``/``take1``: the agent's take-in (services/runtime/admission.py ``Gate.take_all``, of
  what arrived for one step) entered / left (on the thread that takes it in).

``--n`` request→inform round trips (after 50 warm-up ones) give the median of each segment of the
path; ``--raw`` round trips of the bare pair give raw Zenoh's round trip in the same run. The
threads of the three processes are read from ``/proc/<pid>/task/*/`` (``comm``,
``voluntary_ctxt_switches``, ``nonvoluntary_ctxt_switches``) before and after the traced round
trips: context switches per round trip per thread, i.e. how often each thread went to sleep
and was woken up.

An idle agent takes a communicate in on the thread it arrived on (services/runtime/engine.py
``Engine._take_here``); ``ROCO_RECEIVE=agent-thread`` profiles the path that hands every
communicate to the agent's thread instead. The receiving threads poll before they sleep
(services/runtime/polling.py); ``ROCO_RECEIVE_POLL_US=0`` profiles them sleeping at once. The
raw pair sleeps in ``recv()``. The CPU time each process used per round trip is printed last.

Usage: ``python scripts/profile_path.py [--n 2000]``
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing as mp
import os
import statistics
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

Event = tuple[str, int, int]
"""(point, perf_counter_ns, native thread id)."""


def traced_agent(name: str, endpoint: str, conn: Connection) -> None:
    """A synthetic agent process (as services.bench.synthetic.agent_process) with its message
    path traced; ``("trace",)`` on ``conn`` sends the events back."""
    import logging

    from services.bench.synthetic import BenchInitiator, BenchParticipant, bench_spec, serve
    from services.runtime.agent import Agent
    from services.runtime.transport import ZenohTransport

    logging.basicConfig(level=logging.ERROR)
    events: list[Event] = []
    now, tid = time.perf_counter_ns, threading.get_native_id

    class Traced(ZenohTransport):
        def publish(self, key: str, payload: bytes) -> None:
            if key.startswith("roco/fipa/"):
                events.append(("put", now(), tid()))
            super().publish(key, payload)

        def subscribe(self, key_expr: str, callback: Any, *, direct: bool = False) -> None:
            if not key_expr.startswith("roco/fipa/"):  # the clock, the counters: not the inbox
                super().subscribe(key_expr, callback, direct=direct)
                return

            def traced(key: str, payload: bytes) -> None:
                events.append(("cb", now(), tid()))
                callback(key, payload)

            super().subscribe(key_expr, traced, direct=direct)

    base: type[Agent] = BenchInitiator if name.startswith("b_ini") else BenchParticipant

    class TracedGate:
        """The agent's take-in (a compiled ``Gate``), traced around each call."""

        def __init__(self, gate: Any) -> None:
            self.gate = gate

        def take_all(self, inbox: Any, max_open: int) -> None:
            if not any(str(key).startswith("roco/fipa/") for key, _ in inbox):  # no communicate
                self.gate.take_all(inbox, max_open)
                return
            cpu = time.thread_time_ns()
            events.append(("take0", now(), tid()))
            self.gate.take_all(inbox, max_open)
            events.append(("take1", now(), tid()))
            events.append(("take_cpu", time.thread_time_ns() - cpu, 0))

    cls = type(name, (base,), {"name": name})
    transport = Traced([endpoint], links=None)  # as roco bench: ROCO_LINKS
    agent = cls(transport, bench_spec(1), conn)
    engine = agent.engine

    def traced(inner: Callable[..., Any]) -> Callable[..., Any]:
        def send(*args: Any, **kwargs: Any) -> Any:
            events.append(("send", now(), tid()))
            return inner(*args, **kwargs)

        return send

    for method in ("send", "reply"):  # the agent's sends, traced (its engine's methods)
        setattr(engine, method, traced(getattr(engine, method)))
    engine._gate = TracedGate(engine._gate)
    engine.bind()

    def trace(cmd: tuple[Any, ...]) -> bool:
        if cmd[0] != "trace":
            return False
        conn.send(list(events))
        events.clear()
        return True

    serve(agent, transport, conn, trace)


def threads(pid: int) -> dict[int, tuple[str, int, int]]:
    """Thread id → (name, voluntary, non-voluntary context switches) of process ``pid``."""
    import benchlib  # scripts/benchlib.py, beside this file

    return {tid: (u.name, u.voluntary, u.involuntary) for tid, u in benchlib.thread_use(pid).items()}


def cpu_s(pid: int) -> float:
    """CPU time (s, user + system) process ``pid`` has used, from ``/proc/<pid>/stat``."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def switches(before: dict[int, tuple[str, int, int]], after: dict[int, tuple[str, int, int]], n: int) -> str:
    """Context switches per round trip, per thread name (summed over threads of one name):
    ``name voluntary+involuntary`` (voluntary: the thread slept — on a queue, a socket, the GIL;
    involuntary: the scheduler took its core away)."""
    per: dict[str, list[float]] = {}
    for t, (comm, vol, nonvol) in after.items():
        b = before.get(t, (comm, 0, 0))
        got = per.setdefault(comm, [0.0, 0.0])
        got[0] += (vol - b[1]) / n
        got[1] += (nonvol - b[2]) / n
    ranked = sorted(per.items(), key=lambda kv: -(kv[1][0] + kv[1][1]))
    return ", ".join(f"{k} {v:.2f}+{i:.2f}" for k, (v, i) in ranked if v + i >= 0.05)


def by_kind(events: list[Event], kind: str) -> list[Event]:
    return [e for e in events if e[0] == kind]


def segments(ini: list[Event], par: list[Event], n: int) -> list[tuple[str, list[float], str]]:
    """The round trips' segments (µs) from the two agents' events, the last ``n`` of each kind."""
    a = {k: by_kind(ini, k)[-n:] for k in ("send", "put", "cb", "take0", "take1")}
    b = {k: by_kind(par, k)[-n:] for k in ("send", "put", "cb", "take0", "take1")}
    a_send_next = by_kind(ini, "send")[-n:]

    def diff(x: list[Event], y: list[Event]) -> list[float]:
        return [(q[1] - p[1]) / 1e3 for p, q in zip(x, y, strict=False)]

    def same_thread(x: list[Event], y: list[Event]) -> str:
        same = sum(p[2] == q[2] for p, q in zip(x, y, strict=False))
        return "same thread" if same == len(x) else f"another thread ({len(x) - same} of {len(x)})"

    # the initiator's next send follows the inform's take: pair take1[i] with send[i+1]
    return [
        (
            "b_ini0: send() called → put (rest of the step, output buffer dispatched)",
            diff(a["send"], a["put"]),
            same_thread(a["send"], a["put"]),
        ),
        (
            "b_ini0 put → b_par0 Zenoh callback (Zenoh: one hop; ROCO_LINKS=router: two)",
            diff(a["put"], b["cb"]),
            "",
        ),
        (
            "b_par0: Zenoh callback → take-in entered (taken in where it arrived, or handed over)",
            diff(b["cb"], b["take0"]),
            same_thread(b["cb"], b["take0"]),
        ),
        ("b_par0: take-in (decode, checks, protocol state)", diff(b["take0"], b["take1"]), ""),
        ("b_par0: taken → reply's send() called (behaviour step)", diff(b["take1"], b["send"]), ""),
        ("b_par0: send() called → put", diff(b["send"], b["put"]), ""),
        ("b_par0 put → b_ini0 Zenoh callback (Zenoh)", diff(b["put"], a["cb"]), ""),
        (
            "b_ini0: Zenoh callback → take-in entered (taken in where it arrived, or handed over)",
            diff(a["cb"], a["take0"]),
            same_thread(a["cb"], a["take0"]),
        ),
        ("b_ini0: take-in", diff(a["take0"], a["take1"]), ""),
        (
            "b_ini0: take-in, CPU time of the thread that took it in",
            [e[1] / 1e3 for e in by_kind(ini, "take_cpu")[-n:]],
            "",
        ),
        (
            "b_ini0: taken → next request's send() (behaviour step; ends the round trip)",
            diff(a["take1"], a_send_next[1:]),
            "",
        ),
        ("round trip: send() → next send()", diff(a_send_next[:-1], a_send_next[1:]), ""),
    ]


def counters(conn: Connection) -> Counter[str]:
    """A synthetic agent's counters, asked on its pipe (services/bench/synthetic.py ``COUNTERS``)."""
    from services.bench.synthetic import COUNTERS

    conn.send((COUNTERS,))
    if not conn.poll(30):
        raise TimeoutError("a synthetic agent did not give its counters within 30 s")
    got = conn.recv()
    return Counter({str(k): int(v) for k, v in got["counters"].items()})


def main() -> int:
    """Print the figures (module docstring); exit 1 with one ``roco:`` line and no figure when
    the traced round trips were not the work timed (services/bench/messaging.py
    ``check_exchange``: a round trip missing, anything refused or not understood)."""
    from services.bench.messaging import SetupError

    try:
        return _main()
    except SetupError as exc:
        print(f"roco: profile_path: {exc}", file=sys.stderr)
        return 1


def _main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="traced round trips (after 50 warm-up)")
    ap.add_argument("--raw", type=int, default=2000, help="raw Zenoh round trips (after 50 warm-up)")
    args = ap.parse_args()

    from services.bench.messaging import Exchange, check_exchange, no_access_control, request_bytes
    from services.bench.synthetic import WARMUP, raw_process
    from services.fleet.launcher import Fleet, free_port

    run_dir = Path(os.environ.get("TMPDIR", "/tmp")) / f"roco-profile-path-{os.getpid()}"
    (run_dir / "logs").mkdir(parents=True, exist_ok=True)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with no_access_control():
        fleet = Fleet(run_dir, endpoint)
        fleet.start_router()
    ctx = mp.get_context("spawn")
    procs: dict[str, tuple[Any, Connection]] = {}
    try:
        for name, target, extra in (
            ("b_ini0", traced_agent, ("b_ini0",)),
            ("b_par0", traced_agent, ("b_par0",)),
            ("raw_echo0", raw_process, ("echo", 0)),
            ("raw_pinger0", raw_process, ("pinger", 0)),
        ):
            parent, child = ctx.Pipe()
            p = ctx.Process(target=target, args=(*extra, endpoint, child), daemon=True)
            p.start()
            procs[name] = (p, parent)
        for _, conn in procs.values():
            if not conn.poll(120):
                raise TimeoutError("a process did not start")
            conn.recv()
        router_pid = fleet.processes["router"].pid
        pids = {"b_ini0": procs["b_ini0"][0].pid, "b_par0": procs["b_par0"][0].pid, "router": router_pid}
        ini = procs["b_ini0"][1]
        ini.send(("pingpong", 200, 200))  # warm-up: publishers declared, caches filled
        ini.recv()
        for c in ("b_ini0", "b_par0"):
            procs[c][1].send(("trace",))
            procs[c][1].recv()
        counted = {c: counters(procs[c][1]) for c in ("b_ini0", "b_par0")}
        load = os.getloadavg()
        before = {k: threads(p) for k, p in pids.items()}
        cpu_before = {k: cpu_s(p) for k, p in pids.items()}
        ini.send(("pingpong", args.n, 200))
        ini.recv()
        cpu = {k: cpu_s(p) - cpu_before[k] for k, p in pids.items()}
        after = {k: threads(p) for k, p in pids.items()}
        check_exchange(
            counters(procs["b_ini0"][1]) - counted["b_ini0"],
            counters(procs["b_par0"][1]) - counted["b_par0"],
            Exchange({"request": args.n + WARMUP}, {"inform": args.n + WARMUP}),
        )
        traces = {}
        for c in ("b_ini0", "b_par0"):
            procs[c][1].send(("trace",))
            traces[c] = procs[c][1].recv()
        pinger = procs["raw_pinger0"][1]
        raw_pids = {k: procs[k][0].pid for k in ("raw_pinger0", "raw_echo0")} | {"router (raw)": router_pid}
        raw_before = {k: threads(p) for k, p in raw_pids.items()}
        raw_cpu_before = {k: cpu_s(p) for k, p in raw_pids.items()}
        pinger.send(("pingpong", args.raw, request_bytes(200)))
        raw = pinger.recv()["samples_s"]
        raw_cpu = {k: cpu_s(p) - raw_cpu_before[k] for k, p in raw_pids.items()}
        raw_after = {k: threads(p) for k, p in raw_pids.items()}
        n = args.n + 50
        loads = " / ".join(f"{x:.2f}" for x in load)
        print(f"# load average {loads}; {args.n} round trips (+50 warm-up)")
        print(f"raw Zenoh round trip p50: {statistics.median(raw) * 1e6:.0f} µs ({args.raw} round trips)")
        print("\n| segment | p50 µs | p90 µs | thread |\n|---|---|---|---|")
        for label, values, where in segments(traces["b_ini0"], traces["b_par0"], n):
            qs = statistics.quantiles(values, n=10)
            print(f"| {label} | {statistics.median(values):.1f} | {qs[8]:.1f} | {where} |")
        print("\n| process | context switches per round trip, by thread name (voluntary+involuntary) |")
        print("|---|---|")
        for k in pids:
            print(f"| {k} | {switches(before[k], after[k], n)} |")
        for k in raw_pids:
            print(f"| {k} | {switches(raw_before[k], raw_after[k], args.raw + 50)} |")
        per = ", ".join(f"{k} {v / n * 1e6:.0f}" for k, v in cpu.items())
        raw_per = ", ".join(f"{k} {v / (args.raw + 50) * 1e6:.0f}" for k, v in raw_cpu.items())
        print(f"\nCPU per round trip (µs, user + system, /proc/PID/stat): {per}; raw: {raw_per}")
        cbs = {e[2] for e in by_kind(traces["b_par0"], "cb")}
        takes = {e[2] for e in by_kind(traces["b_par0"], "take0")}
        print(f"\nb_par0: callbacks ran on {len(cbs)} Zenoh thread(s), takes on {len(takes)} agent thread(s)")
    finally:
        for _, conn in procs.values():
            with contextlib.suppress(OSError, ValueError):
                conn.send(("stop",))
        for p, _ in procs.values():
            p.join(10)
            if p.is_alive():
                p.kill()
                p.join(5)
        fleet.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
