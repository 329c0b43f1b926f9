"""CPU cost of roco's runtime per communicate, without a network: the benchmark's synthetic
agents (services/bench/messaging.py) in one process on a transport that only collects what
is published, so that what is timed is the agent's own send and receive path (content and
envelope encoding, interface and protocol-state checks, dedup, decoding, validation, input
queue, FSM step): the runtime's hot path (docs/benchmarks.md, "The path of one communicate").

- ``round trip``: request → inform → back, ``--n`` times: 2 sends and 2 receives each;
- ``stream send`` / ``stream receive``: ``--n`` informs of one fipa-subscribe conversation,
  sent by the participant, then taken in by the initiator.

Prints µs per round trip / per communicate (``time.perf_counter``); ``--profile`` prints
cProfile's 30 most expensive functions of each instead (slower: figures then include the
profiler's own cost).

``--stages`` prints where a round trip's time goes, stage by stage: cProfile's own time of every
function (its ``tottime``), each function given to the stage its module and name say
(:data:`STAGES`: decoding, the received communicate's checks, admission, the protocol state,
the duplicate filter, the replies awaited, routing to a role, the handler, the agent's
elementary actions and hand-offs, sending, encoding, the put; a builtin's time goes to the
stages of its callers), in µs per round trip and as a share. Run it with
``ROCO_INTERPRETED=1``: a compiled module's functions have no Python frames for cProfile, and
their time would land in their callers' stage (the script says when).

``--cpu`` prints CPU time (``time.process_time``) instead, the median and the least of
``--repeat`` runs, each after a full garbage collection (else one of the earlier runs'
garbage lands in some runs, ≈ 15 ms each): steadier than wall time on a machine other jobs
share (the way to compare two commits).

Usage: ``python scripts/profile_runtime.py [--n 5000] [--profile | --stages | --cpu [--repeat 9]]``
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import pstats
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from services.bench.messaging import (
    WARMUP,
    BenchInitiator,
    BenchParticipant,
    Exchange,
    SetupError,
    bench_spec,
    check_exchange,
)


class Collect:
    """A transport that keeps what is published (key, payload) and delivers nothing."""

    def __init__(self) -> None:
        self.out: list[tuple[str, bytes]] = []

    def publish(self, key: str, payload: bytes) -> None:
        self.out.append((key, payload))

    def subscribe(self, key_expr: str, callback: Any) -> None:
        """Nothing arrives by itself: the script hands payloads over."""

    def announce(self, key: str) -> None:
        """No liveliness here."""

    def watch(self, key_expr: str, callback: Any) -> None:
        """No liveliness here."""

    def close(self) -> None:
        """Nothing to close."""


class Results:
    """Stands for the benchmark's pipe: keeps the last result."""

    last: dict[str, Any] | None = None

    def send(self, result: dict[str, Any]) -> None:
        self.last = result


def pair() -> tuple[Any, Any]:
    spec = bench_spec(1)
    ini = type("b_ini0", (BenchInitiator,), {"name": "b_ini0"})(Collect(), spec, Results())
    par = type("b_par0", (BenchParticipant,), {"name": "b_par0"})(Collect(), spec, Results())
    ini.peers.add("b_par0")
    return ini, par


def hand(src: Any, dst: Any) -> None:
    """Deliver everything ``src`` published to ``dst``'s input queue and acquire it."""
    for key, payload in src.engine.transport.out:
        dst.engine._on_payload(key, payload)
    src.engine.transport.out.clear()
    dst.engine.acquire(0)


def round_trips(n: int) -> float:
    ini, par = pair()
    ini.post(("pingpong", n, 200))
    ini.engine.acquire(0)
    t0 = time.perf_counter()
    ini._work()
    ini.engine.dispatch()
    while ini.job is not None and ini.engine.transport.out:  # else the exchange stopped: checked below
        hand(ini, par)
        par._serve()
        par.engine.dispatch()
        hand(par, ini)
        ini._work()
        ini.engine.dispatch()
    took = (time.perf_counter() - t0) / (n + WARMUP) * 1e6
    check_exchange(ini.counters, par.counters, Exchange({"request": n + WARMUP}, {"inform": n + WARMUP}))
    return took


def stream(n: int) -> tuple[float, float]:
    ini, par = pair()
    ini.post(("stream", n, 200))
    ini.engine.acquire(0)
    ini._work()
    ini.engine.dispatch()
    hand(ini, par)
    par._serve()
    par.engine.dispatch()
    agree = list(par.engine.transport.out)
    par.engine.transport.out.clear()
    t0 = time.perf_counter()
    while par.stream is not None:
        par._stream()
        par.engine.dispatch()
    send_us = (time.perf_counter() - t0) / n * 1e6
    informs = par.engine.transport.out
    par.engine.transport.out = agree
    hand(par, ini)
    ini._work()
    t0 = time.perf_counter()
    for i in range(0, len(informs), 256):
        for key, payload in informs[i : i + 256]:
            ini.engine._on_payload(key, payload)
        ini.engine.acquire(0)
        ini._work()
    receive_us = (time.perf_counter() - t0) / n * 1e6
    check_exchange(ini.counters, par.counters, Exchange({"subscribe": 1}, {"agree": 1, "inform": n}))
    return send_us, receive_us


def profiled(fn: Callable[[], object]) -> None:
    prof = cProfile.Profile()
    prof.enable()
    fn()
    prof.disable()
    pstats.Stats(prof).sort_stats("tottime").print_stats(30)


STAGES: tuple[tuple[str, str, str], ...] = (
    ("decode", "shared/fipa_codec/", "decode"),
    ("encode", "shared/fipa_codec/", "encode"),
    ("codec, other", "shared/fipa_codec/", ""),
    ("received: checks", "services/runtime/intake.py", ""),
    ("received: admission", "services/runtime/admission.py", ""),
    ("protocol state", "services/runtime/protocol_state.py", ""),
    ("duplicate filter", "services/runtime/dedup.py", ""),
    ("replies awaited", "services/runtime/replies.py", ""),
    ("specification's answers", "services/runtime/lookups.py", ""),
    ("routing to a role", "services/runtime/roles/", ""),
    ("sending", "services/runtime/emission.py", ""),
    ("sending: interface checks", "services/runtime/send_checks.py", ""),
    ("elementary actions, hand-offs", "services/runtime/engine.py", ""),
    ("the agent's context", "services/runtime/agent.py", ""),
    ("behaviours", "services/runtime/behaviour.py", ""),
    ("the handler (benchmark agents)", "services/bench/", ""),
    ("the put (collecting transport)", "scripts/profile_runtime.py", "publish"),
    ("this script's loop", "scripts/profile_runtime.py", ""),
    ("decode", "~", "decode"),
    ("encode", "~", "encode"),
    ("msgspec, other", "~", "msgspec"),
)
"""(stage, module path part, function name part): a function goes to the first row whose path
part is in its file's path and whose name part is in its name ("" matches any); the rest is
"other" (the profile loop, Python's own)."""


def stage_of(path: str, name: str) -> str:
    """The stage of :data:`STAGES` a function of ``path`` named ``name`` belongs to."""
    for stage, where, called in STAGES:
        if where in path and called in name:
            return stage
    return "other"


def stages(n: int) -> int:
    """Print the stage table of ``n`` round trips (module docstring)."""
    from services.runtime import native

    loaded = (sys.modules.get(f"services.runtime.{m}") for m in native.COMPILED)
    compiled = [m.__name__ for m in loaded if m is not None and str(m.__file__).endswith(".so")]
    prof = cProfile.Profile()
    prof.enable()
    round_trips(n)
    prof.disable()
    by: dict[str, float] = {}
    st = pstats.Stats(prof)
    for (path, _line, name), row in st.stats.items():  # type: ignore[attr-defined]
        own = stage_of(path, name)
        if path != "~" or own != "other":
            by[own] = by.get(own, 0.0) + row[2]
            continue
        for (cpath, _cline, cname), crow in row[4].items():  # a builtin: its time to its callers' stages
            by[stage_of(cpath, cname)] = by.get(stage_of(cpath, cname), 0.0) + crow[2]
    total = sum(by.values())
    per = (n + WARMUP) / 1e6
    print("| stage | µs per round trip (profiled) | share |")
    print("|---|---:|---:|")
    for stage, t in sorted(by.items(), key=lambda kv: -kv[1]):
        print(f"| {stage} | {t / per:.1f} | {100 * t / total:.1f} % |")
    print(f"| all | {total / per:.1f} | 100 % |")
    if compiled:
        print(f"(compiled, their time in their callers' stages: {', '.join(compiled)}; ROCO_INTERPRETED=1)")
    return 0


def main() -> int:
    """Print the figures (module docstring); exit 1 with one ``roco:`` line, and no figure,
    when the pair did not exchange what is timed or anything was refused or not understood
    (services/bench/messaging.py ``check_exchange``)."""
    try:
        return _main()
    except SetupError as exc:
        print(f"roco: profile_runtime: {exc}", file=sys.stderr)
        return 1


def _main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=5000)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--stages", action="store_true", help="a round trip's time by stage (ROCO_INTERPRETED=1)")
    ap.add_argument("--cpu", action="store_true", help="CPU time, median and least of --repeat runs")
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args()
    if args.cpu:
        rts, streams = [], []
        for _ in range(args.repeat):
            gc.collect()  # the runs before left garbage whose full collection would land in a run
            c = time.process_time()
            round_trips(args.n)
            rts.append((time.process_time() - c) / (args.n + WARMUP) * 1e6)
            gc.collect()
            c = time.process_time()
            stream(args.n)
            streams.append((time.process_time() - c) / args.n * 1e6)
        for label, v in (
            ("round trip (2 sends + 2 receives)", rts),
            ("stream, one send + one receive", streams),
        ):
            print(f"CPU per {label}: median {statistics.median(v):.1f} µs, least {min(v):.1f} µs")
        return 0
    if args.stages:
        return stages(args.n)
    if args.profile:
        profiled(lambda: round_trips(args.n))
        profiled(lambda: stream(args.n))
        return 0
    print(f"round trip (2 sends + 2 receives): {round_trips(args.n):.1f} µs")
    send_us, receive_us = stream(args.n)
    print(f"stream send: {send_us:.1f} µs per communicate; stream receive: {receive_us:.1f} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
