"""A stop's latency: from the line reaching a_hi to ag_ex's control loop beginning the halt.

Starts a fleet as ``roco run`` does (a router on a free loopback port, the traffic recorder, one
process per agent, access control on; ag_ex's loop as fast as it can, or paced with
``--realtime``), waits for a_km's first knowledge, runs one whole pour (its time is printed),
then ``--stops`` halts per condition, the conditions taking turns:

1. says "pour the jar into the bowl" (a pour after a stop starts from wherever the safe stop
   put the jar; the kitchen is fresh after the whole pour and after any pour that succeeded:
   a_km refuses a plan that pours an empty jar);
2. waits a random time, uniform in [0.3 s, ``--window``] from a_co's agreement (default 6 s,
   the shortest pour as fast as it can; 16 s paced): a random moment of the pour (taking the jar
   out, turning, carrying, lowering, tilting, letting it run out, tilting back);
3. ``plain``: puts "stop" on a_hi's key (``roco/human/in``, as ``roco send`` does); ``long
   line before``: first a 1,000-character line of ``--long-shape`` (scripts/bench_reading.py's
   shapes; ``command``, the default: "please … pour the jar into the bowl", the slowest line a_hi
   reads), then "stop" ``--gap-ms`` later;
4. waits for the commands' final reports (the pour ``stopped`` once a_ta's safe stop has put
   the jar down; a long command line read before the stop is stopped too).

Measured, on this machine's one wall clock (``time.time``): from the put of "stop" (the line
reaches a_hi one Zenoh hop later: a few hundred µs, counted in the figure) to the ``Halting``
wall time ag_ex's loop process logs in the cycle it replaced the running command by the halt
(velma/executor/process.py; read from ``logs/ag_ex.log``). Where the time goes, from this
process's own subscriber to every communicate (one hop after each put): a_hi's ``cancel`` to
a_co (C2), a_co's ``cancel`` to a_ta (C1), a_ta's ``cancel`` to ag_ex (C5). A stop that finds
no motion to halt (the robot between two commands, observing, or the pour over) has no halt:
it is counted apart and another pour is started, until each condition has ``--stops`` halts.
After the whole pour, a pour that succeeded or failed, or three stops in a row finding nothing
moving (the jar emptied, or left where the robot cannot take it), a new fleet starts from a
fresh kitchen.

Prints the machine, a line per stop, then p50 / p99 / max (ms) per condition, and the median
of each hop; :func:`measure` returns these figures (:class:`StopFigures`, ``roco bench``'s
``stop`` part). The run folder is removed at the end, unless ``--keep``.

Usage: ``python scripts/bench_stop.py [--stops 20] [--realtime] [--window S] [--gap-ms 20]
[--long-shape command|words] [--seed 1] [--keep]``
"""

from __future__ import annotations

import argparse
import functools
import queue
import random
import re
import shutil
import statistics
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)
import msgspec  # noqa: E402
import zenoh  # noqa: E402
from bench_reading import line as reading_line  # noqa: E402

from services.bench.messaging import percentile  # noqa: E402
from services.bench.setup_check import check_agents  # noqa: E402
from services.fleet.launcher import AGENT_ORDER, Fleet, free_port  # noqa: E402
from services.monitor import is_world_update  # noqa: E402
from services.runtime import keys  # noqa: E402
from services.runtime.human import FINAL_REPORTS, MAX_LINE_CHARS, HumanInput, HumanReport, ReportKind  # noqa: E402
from services.runtime.session import open_client  # noqa: E402
from services.scenario.model import DEFAULT_COMMAND  # noqa: E402
from shared.fipa_codec import Performative, decode  # noqa: E402
from shared.fipa_codec.batch import unpack  # noqa: E402
from shared.settings import Settings  # noqa: E402

POUR = DEFAULT_COMMAND
HALTING = re.compile(r"halted by a cancel at wall time (\d+\.\d+)")
CONDITIONS = ("plain", "long line before")
HOPS = (("C2", "a_hi", "a_co"), ("C1", "a_co", "a_ta"), ("C5", "a_ta", "ag_ex"))
"""The cancels a stop sends on its way to the loop: (channel, sender, receiver)."""
REPORT_S = 240.0
"""s to wait for a command's final report."""


@dataclass
class Stop:
    """One stop: when its line was put, and when each hop's cancel and the halt were seen."""

    condition: str
    line_t: float
    hops: dict[str, float] = field(default_factory=dict)
    halt_t: float | None = None

    @property
    def latency_ms(self) -> float | None:
        return None if self.halt_t is None else (self.halt_t - self.line_t) * 1e3


class Watch:
    """This process's view of the fleet: a_hi's reports, every communicate's arrival time."""

    def __init__(self, session: zenoh.Session) -> None:
        self.reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
        self.cancels: list[tuple[float, str]] = []  # (arrival, "C2") of each cancel of a HOP
        self.knowledge = threading.Event()
        self._lock = threading.Lock()
        decoder = msgspec.json.Decoder(HumanReport)
        session.declare_subscriber(
            keys.HUMAN_OUT, lambda s: self.reports.put(decoder.decode(s.payload.to_bytes()))
        )
        session.declare_subscriber(keys.FIPA_ALL, self._on_fipa)

    def _on_fipa(self, sample: zenoh.Sample) -> None:
        now = time.time()
        key = str(sample.key_expr)
        for payload in unpack(sample.payload.to_bytes()):
            if key == keys.fipa_key("C6", "a_ta", "a_km") and is_world_update(payload):
                self.knowledge.set()
            for channel, sender, receiver in HOPS:
                cancel = key == keys.fipa_key(channel, sender, receiver)
                if cancel and decode(payload).performative is Performative.CANCEL:
                    with self._lock:
                        self.cancels.append((now, channel))

    def first_cancels(self, after: float) -> dict[str, float]:
        """The first cancel of each hop seen after ``after`` (POSIX s)."""
        with self._lock:
            seen = list(self.cancels)
        out: dict[str, float] = {}
        for t, channel in seen:
            if t >= after and channel not in out:
                out[channel] = t
        return out

    def finals(self, *request_ids: str, timeout: float = REPORT_S) -> dict[str, HumanReport]:
        """The final report of each of ``request_ids``; first, ``accepted`` of the first."""
        out: dict[str, HumanReport] = {}
        deadline = time.monotonic() + timeout
        while len(out) < len(request_ids):
            report = self.reports.get(timeout=max(0.1, deadline - time.monotonic()))
            if report.request_id in request_ids and report.kind in FINAL_REPORTS:
                out[report.request_id] = report
        return out

    def accepted(self, request_id: str, timeout: float = REPORT_S) -> HumanReport:
        """``request_id``'s first report (``accepted`` when a_co took the command)."""
        deadline = time.monotonic() + timeout
        while True:
            report = self.reports.get(timeout=max(0.1, deadline - time.monotonic()))
            if report.request_id == request_id:
                return report


def say(session: zenoh.Session, text: str, request_id: str) -> float:
    """Put ``text`` on a_hi's key; returns the wall time of the put."""
    payload = msgspec.json.encode(HumanInput(text=text, request_id=request_id))
    t = time.time()
    session.put(keys.HUMAN_IN, payload)
    return t


def halts(log: Path) -> list[float]:
    """Every ``Halting`` wall time ag_ex's log holds, in order."""
    if not log.exists():
        return []
    return [float(m.group(1)) for m in HALTING.finditer(log.read_text(errors="replace"))]


IDLE_IN_ROW = 3
"""Pours not accepted, or stopped with nothing moving, in a row before a fresh kitchen (a pour
that failed, or succeeded before its stop came: at once)."""
MAX_KITCHENS = 16
"""Fresh kitchens (fleets) the benchmark starts at most before it gives up."""


@dataclass
class StopFigures:
    """What :func:`measure` found: each condition's halts, and how the run was made."""

    asked: int
    """halts asked for per condition (``--stops``)"""
    halts_ms: dict[str, list[float]]
    """per condition (``CONDITIONS``): ms from the put of "stop" to ag_ex's ``Halting``, in order"""
    idle: dict[str, int]
    """per condition: stops that found no motion to halt (not in ``halts_ms``)"""
    hops_ms: dict[str, dict[str, float | None]]
    """per condition, per hop (``HOPS``' channel): the median ms from the put of "stop" to this
    process seeing that cancel, over the stops that halted (None: never seen)"""
    first_pour_s: float
    """wall s of the first, whole pour (from a_hi's first report to its final one)"""
    first_pour: str
    """its final report's kind (``succeeded``, ``failed``, …)"""
    window_s: float
    """stops at U(0.3, window_s) s after a_co's agreement"""
    realtime: bool
    """ag_ex's loop paced to wall time (else as fast as it can)"""
    long_shape: str
    long_chars: int
    """the long line's shape (scripts/bench_reading.py) and length, characters"""
    gap_ms: float
    """ms from the long line to the stop"""
    kitchens: int = 1
    """fleets started, each with a fresh kitchen (a new one when the robot could no longer pour)"""

    def percentile_ms(self, condition: str, q: float) -> float | None:
        """The ``q`` quantile (0–1, nearest rank) of ``condition``'s halts (None: no halt)."""
        ms = self.halts_ms.get(condition, [])
        return percentile(ms, q * 100) if ms else None


class Kitchen:
    """One fleet as ``roco run`` starts it, with a fresh kitchen (ag_ex's world) and this
    process's :class:`Watch` on it; :meth:`close` ends it and removes its run folder unless
    ``keep`` (then echoed)."""

    def __init__(self, realtime: bool, keep: bool, echo: Callable[[str], object]) -> None:
        self.keep, self.echo = keep, echo
        self.run_dir = Path(tempfile.mkdtemp(prefix="roco-bench-stop-"))
        (self.run_dir / "logs").mkdir()
        env = {Settings.env_name("realtime"): "1" if realtime else "0"}
        self.fleet = Fleet(self.run_dir, f"tcp/127.0.0.1:{free_port()}", env=env)
        self.session: zenoh.Session | None = None
        try:
            self.fleet.start_router()
            self.session = open_client(self.fleet.endpoint)
            self.watch = Watch(self.session)
            self.fleet.start_recorder()
            self.fleet.wait_alive(self.session, ["recorder"], timeout=60)
            self.fleet.start_agents()
            self.fleet.wait_alive(self.session, AGENT_ORDER, timeout=180)
            if not self.watch.knowledge.wait(120):
                raise RuntimeError("a_km received no first knowledge within 120 s")
        except BaseException:
            self.close()
            raise
        self.log = self.run_dir / "logs" / "ag_ex.log"

    def say(self, text: str, request_id: str) -> float:
        assert self.session is not None
        return say(self.session, text, request_id)

    def check(self, during: str) -> None:
        """Raise SetupRefused when an agent counted anything refused, not understood or against
        its protocol so far (services/bench/setup_check.py)."""
        assert self.session is not None
        check_agents(self.session, AGENT_ORDER, during)

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
        self.fleet.stop()
        if self.keep:
            self.echo(f"run folder: {self.run_dir}")
        else:
            shutil.rmtree(self.run_dir, ignore_errors=True)


def measure(
    stops: int,
    realtime: bool = False,
    window: float | None = None,
    gap_ms: float = 20.0,
    long_shape: str = "command",
    seed: int = 1,
    keep: bool = False,
    echo: Callable[[str], object] = print,
) -> StopFigures:
    """Start a fleet, run one whole pour, then pours stopped until each condition has ``stops``
    halts (the module's docstring says how; ``window`` defaults to 16 s paced, else 6 s).
    Stopped again and again, the robot may leave the jar where it can no longer take it (a
    safe stop puts it down where the robot stands), and a pour that ran to its end empties the
    jar (a_km refuses to plan pouring an empty jar): after the whole pour, after a pour that
    failed or succeeded, and after ``IDLE_IN_ROW`` stops in a row found nothing moving, the fleet
    is ended and a new one starts from a fresh kitchen (counted in ``kitchens``). ``echo`` is
    given a line per stop as it is measured; run folders are removed unless ``keep`` (then echoed). Raises
    RuntimeError when a fleet does not come up, or ``MAX_KITCHENS`` kitchens were used, and
    SetupRefused (a RuntimeError) when an agent counted anything refused, not understood or
    against its protocol in the first pour, before any stop."""
    rng = random.Random(seed)
    long_line = reading_line(long_shape, MAX_LINE_CHARS)
    window = window if window is not None else (16.0 if realtime else 6.0)
    records: list[Stop] = []
    idle = dict.fromkeys(CONDITIONS, 0)  # stops that found no motion to halt

    def halted(condition: str) -> int:
        return sum(s.condition == condition and s.halt_t is not None for s in records)

    kitchen = Kitchen(realtime, keep, echo)
    kitchens = 1
    try:
        rid = f"p-{uuid.uuid4().hex[:6]}"
        kitchen.say(POUR, rid)
        t0 = kitchen.watch.accepted(rid).kind
        start = time.monotonic()
        first = kitchen.watch.finals(rid)[rid]
        pour_s = time.monotonic() - start
        kitchen.check("the first pour, before any stop")
        kitchen.close()  # the whole pour emptied the jar: the stops' pours start full
        kitchen = Kitchen(realtime, keep, echo)
        kitchens += 1
        echo(
            f"ag_ex's loop {'paced to wall time' if realtime else 'as fast as it can'}; "
            f"first pour: {first.kind.value} in {pour_s:.1f} s ({t0.value} first); "
            f"stops at U(0.3, {window:.0f}) s after a_co agreed; long line: {long_shape}, "
            f"{len(long_line)} characters, {gap_ms:.0f} ms before the stop"
        )
        n = 0
        spoiled = 0  # pours not accepted, or stopped with nothing moving, in a row
        why = ""  # why the next pour needs a fresh kitchen
        while min(halted(c) for c in CONDITIONS) < stops:
            if spoiled >= IDLE_IN_ROW:
                if kitchens >= MAX_KITCHENS:
                    raise RuntimeError(f"the robot could not pour in {kitchens} fresh kitchens")
                echo(f"  a fresh kitchen: {why or f'{spoiled} pours in a row found nothing to halt'}")
                kitchen.close()
                kitchen = Kitchen(realtime, keep, echo)
                kitchens += 1
                spoiled, why = 0, ""
            condition = CONDITIONS[n % 2]
            n += 1
            if halted(condition) >= stops:
                continue
            pour, stop = f"p-{uuid.uuid4().hex[:6]}", f"s-{uuid.uuid4().hex[:6]}"
            kitchen.say(POUR, pour)
            if kitchen.watch.accepted(pour).kind is not ReportKind.ACCEPTED:
                spoiled += 1
                continue
            time.sleep(rng.uniform(0.3, window))  # a random moment of the pour
            before = len(halts(kitchen.log))
            if condition == "long line before":
                kitchen.say(long_line, f"l-{uuid.uuid4().hex[:6]}")
                time.sleep(gap_ms / 1e3)
            record = Stop(condition, kitchen.say("stop", stop))
            ended = kitchen.watch.finals(pour, stop)
            time.sleep(0.5)  # the long line's command, when it was read, is stopped too
            seen = [t for t in halts(kitchen.log)[before:] if t >= record.line_t]
            record.halt_t = seen[0] if seen else None
            record.hops = kitchen.watch.first_cancels(record.line_t)
            if record.halt_t is None:
                idle[condition] += 1
            records.append(record)
            outcome = ended[pour].kind
            if outcome in (ReportKind.FAILED, ReportKind.SUCCEEDED):  # the jar may be empty
                spoiled, why = IDLE_IN_ROW, f"the pour {outcome.value}"
            else:  # a pour that halted shows the kitchen usable
                spoiled = spoiled + 1 if record.halt_t is None else 0
            done = record.latency_ms
            hops = ", ".join(
                f"{c} {(record.hops[c] - record.line_t) * 1e3:.1f}" for c, _, _ in HOPS if c in record.hops
            )
            echo(
                f"  {len(records):3d} {condition:<17} "
                + (f"{done:8.1f} ms" if done is not None else "   no halt")
                + f"  (pour {ended[pour].kind.value}; cancels seen at ms: {hops or 'none'})"
            )
    finally:
        kitchen.close()
    halts_ms: dict[str, list[float]] = {}
    hops_ms: dict[str, dict[str, float | None]] = {}
    for c in CONDITIONS:
        got = [s for s in records if s.condition == c and s.latency_ms is not None]
        halts_ms[c] = [s.latency_ms for s in got if s.latency_ms is not None]
        hops_ms[c] = {}
        for channel, _, _ in HOPS:
            values = [(s.hops[channel] - s.line_t) * 1e3 for s in got if channel in s.hops]
            hops_ms[c][channel] = statistics.median(values) if values else None
    return StopFigures(
        asked=stops,
        halts_ms=halts_ms,
        idle=idle,
        hops_ms=hops_ms,
        first_pour_s=pour_s,
        first_pour=first.kind.value,
        window_s=window,
        realtime=realtime,
        long_shape=long_shape,
        long_chars=len(long_line),
        gap_ms=gap_ms,
        kitchens=kitchens,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--stops", type=int, default=20, help="halts measured per condition")
    parser.add_argument("--realtime", action="store_true", help="pace ag_ex's loop to wall time")
    parser.add_argument("--window", type=float, default=None, help="s: stops at U(0.3, S) into a pour")
    parser.add_argument("--gap-ms", type=float, default=20.0, help="ms from the long line to the stop")
    parser.add_argument("--long-shape", choices=("command", "words"), default="command")
    parser.add_argument("--seed", type=int, default=1, help="draws the moments of the stops")
    parser.add_argument("--keep", action="store_true", help="keep the run folder (printed)")
    args = parser.parse_args()
    print(benchlib.machine(("eclipse-zenoh", "mujoco", "pin", "lark")))
    try:
        figures = measure(
            args.stops,
            realtime=args.realtime,
            window=args.window,
            gap_ms=args.gap_ms,
            long_shape=args.long_shape,
            seed=args.seed,
            keep=args.keep,
            echo=functools.partial(print, flush=True),
        )
    except RuntimeError as exc:
        raise SystemExit(f"bench_stop: {exc}") from exc
    print()
    hops = " | ".join(h[0] for h in HOPS)
    print(f"| condition | halts | p50 ms | p99 ms | max ms | no motion to halt | {hops} |")
    print(f"|---|---|---|---|---|---|{'---|' * len(HOPS)}")
    for c in CONDITIONS:
        ms = figures.halts_ms[c]
        hop_ms = [figures.hops_ms[c][channel] for channel, _, _ in HOPS]
        cells = " | ".join("—" if h is None else f"{h:.1f}" for h in hop_ms)
        if ms:
            spread = f"{statistics.median(ms):.1f} | {percentile(ms, 99):.1f} | {max(ms):.1f}"
        else:
            spread = "— | — | —"
        print(f"| {c} | {len(ms)} | {spread} | {figures.idle[c]} | {cells} |")
    print("(hops: the median ms from the stop's put to this process seeing each cancel)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
