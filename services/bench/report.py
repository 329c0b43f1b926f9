"""What ``roco bench`` writes to docs/benchmarks.md: the head (what the document answers, the
run's command, commit, machine and load), the targets met or missed, and one section per part
(what was timed, from where to where, how many times, in which processes; then its table).

The functions here only render: services/bench/runner.py runs the parts and passes their figures.
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import statistics
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from services.bench.gateway import GatewayFigures
from services.bench.jade import JadeFigures
from services.bench.messaging import (
    STREAM_BATCH,
    ConcurrentFigures,
    Latency,
    MessagingFigures,
    PairFigures,
    ScaleRow,
    Throughput,
    percentile,
    request_bytes,
)
from services.bench.parts import (
    POUR,
    CodecRow,
    FleetFigures,
    MemoryFigures,
    PlanningFigures,
    QueryRow,
    TaskRun,
)
from services.bench.quiet import quiet_rule
from services.bench.spade import SpadeFigures
from services.runtime.human import MAX_LINE_CHARS
from services.runtime.zenoh_config import links_setting

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("eclipse-zenoh", "msgspec", "mujoco", "pin", "pyoxigraph", "gtpyhop-core")
TARGET_RT_RATIO = 1.3
"""roco's request → inform round trip over raw Zenoh's on the same link, both polling, access
control and mutual TLS on (p50), at most."""
TARGET_TPUT = 50_000.0
"""One pair's one-way stream of 200 B informs, one per put, access control and mutual TLS on,
communicates per second, at least."""
TARGET_SPADE_RT = 3.0
"""SPADE's round trip over roco's (p50), at least."""
TARGET_SPADE_TPUT = 10.0
"""roco's stream over SPADE's, at least."""
TARGET_SCALE_SHARE = 0.6
"""The most agents' all-pairs rate over the fewest's (100 against 10), at least."""
TARGET_PLAN_1_S = 2.0
"""Plan #1 of the pour, request → plan with a_km's queries (s), at most."""
TARGET_AGENT_MIB = 35.0
"""An idle synthetic agent's VmRSS (MiB), at most."""
TARGET_FLEET_MIB = 350.0
"""``roco up``'s fleet in all, at rest (the sum of its processes' PSS, MiB), at most."""
TARGET_UP_S = 3.0
"""``roco up`` from its start to every agent alive (s), at most."""
TARGET_GATEWAY_BURST_S = 10.0
"""500 peers posting to ``roco gateway`` at once: the last answered within (s), at most."""
TARGET_GATEWAY_RSS_MIB = 100.0
"""The gateway's peak RSS over its RSS before, for any one worst request (MiB), at most."""
TARGET_GATEWAY_CPU_S = 1.0
"""The gateway's CPU time for any one worst request until the next message is answered (s), at most."""
TARGET_STOP_P99_MS = 250.0
"""A stop, from the line reaching a_hi to ag_ex's halt of the commanded motion, p99 (ms), at most,
whatever came before it."""
PAPER_PLAN_1_TEXT = "The paper's plan #1 took 55 s and 1,598 communicates."

TITLE = "# roco benchmarks"
INTRO = [
    "What roco costs on one machine: encoding a communicate; a round trip and a stream between two "
    "agents, beside raw Zenoh (its transport), SPADE and JADE; a_km's answers; a_pl's plan; the fleet's "
    "start-up and memory; the whole pour with ag_ex's 1 kHz loop; up to 100 agent processes; the "
    "ACL gateway under load and under attack; a stop, from the line to the halt; a_hi's reading "
    "time against the length of a line.",
    "",
    "`roco bench` (services/bench/) wrote it from the one run described below; `--only NAME` runs "
    "the parts named in brackets. The last section says how to reproduce the figures and what "
    "limits them. The loop alone, physics, camera and pour over randomised scenes (a_ta's verdict "
    "against the simulation's truth, failures planted by spheres removed from the jar): "
    "[bench/loop.md](bench/loop.md), [bench/physics.md](bench/physics.md), "
    "[bench/observe.md](bench/observe.md), [bench/pour_seeds_fleet.md](bench/pour_seeds_fleet.md), "
    "[executor.md](executor.md).",
]
RUN_TITLE = "## This run"
TARGETS_TITLE = "Targets"
TARGETS_INTRO = "The goals roco is measured against (`TARGET_*`, services/bench/report.py), in this run:"
NO_TARGETS = "- (no part with a target was run)"
MISSED, MET = "Missed:", "Met:"
VERDICT = re.compile(r"target[^()]*\): (met|missed)")
"""A target's verdict in a verdict line: ``(target ≤ 350 MiB): missed``; a line may hold two."""


@dataclass(frozen=True)
class Counts:
    """How much each part measures: ``roco bench``'s full counts, or ``--quick``'s (:meth:`of`)."""

    content_bytes: int = 200
    """Content of every communicate of parts 2–3 and 8 (B)."""
    rounds: int = 3
    """Rounds of part 2 (raw and roco ping-pong and streams, in turn)."""
    round_trips: int = 2000
    """Timed round trips per round and system, after 50 warm-up ones."""
    communicates: int = 50_000
    """Communicates per stream."""
    spade_round_trips: int = 1000
    spade_messages: int = 5000
    jade_round_trips: int = 5000
    """Part 3b: timed round trips on JADE, after ``jade_warmup`` ones; its stream has
    ``communicates`` informs, after ``jade_warmup`` ones."""
    jade_warmup: int = 2000
    """Part 3b: round trips, then informs, sent before the timed ones (the JIT's warm-up)."""
    km_timed: int = 200
    """Timed calls per a_km query, after 10 warm-up ones."""
    scale_round_trips: int = 1000
    """Part 8's measured pair: round trips (one round)."""
    scale_communicates: int = 20_000
    """Part 8's measured pair: communicates of its stream."""
    scale_all_pairs: int = 500
    """Part 8: round trips of every initiator when all pairs run at once, after 50 warm-up ones."""
    scale_all_rounds: int = 3
    """Part 8: runs of all pairs at once per agent count (the median is reported)."""
    stops: int = 20
    """Part 10: halts measured per condition."""
    reading_repeats: int = 50
    """Part 11: timed lines per shape and length, after 3 warm-up ones."""

    @classmethod
    def of(cls, quick: bool) -> Counts:
        """The full counts, or ``--quick``'s: a smoke test of the command, not figures to quote."""
        if not quick:
            return cls()
        return cls(
            content_bytes=200,
            rounds=1,
            round_trips=300,
            communicates=5000,
            spade_round_trips=200,
            spade_messages=1000,
            jade_round_trips=300,
            jade_warmup=200,
            km_timed=30,
            scale_round_trips=200,
            scale_communicates=5000,
            scale_all_pairs=50,
            scale_all_rounds=1,
            stops=2,
            reading_repeats=5,
        )


@dataclass(frozen=True)
class Section:
    """One part of the document: its heading (without ``## ``), how it was measured, its table."""

    title: str
    how: list[str]
    table: list[str]

    def lines(self) -> list[str]:
        """The Markdown lines of the section, a blank line after it."""
        return [f"## {self.title}", "", *self.how, *([""] if self.how else []), *self.table, ""]


def cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo (else ``platform``'s guess)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def mem_total_gib() -> float:
    """MemTotal of /proc/meminfo in GiB (0.0 when unknown)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / 1024**2
    except OSError:
        pass
    return 0.0


def load() -> str:
    """The 1, 5 and 15 min load averages (os.getloadavg)."""
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


def commit() -> str:
    """The repository's HEAD commit, short, with ``+ working tree`` when files are changed."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return f"{head}{' + working tree' if dirty else ''}" if head else "unknown"


def machine_lines(command: str, load_start: str, load_end: str, started: float, seconds: float) -> list[str]:
    """The header of docs/benchmarks.md: command, date, machine, versions, load."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    libs = []
    for p in PACKAGES:
        try:
            libs.append(f"{p} {version(p)}")
        except PackageNotFoundError:
            libs.append(f"{p} not installed")
    date = datetime.datetime.fromtimestamp(started).astimezone().strftime("%Y-%m-%d %H:%M %Z")
    return [
        f"- Command: `{command}` (took {seconds:.0f} s), at commit {commit()}, {date}.",
        f"- CPU: {cpu_model()}, {usable} of {os.cpu_count()} cores usable; memory {mem_total_gib():.1f} GiB; "
        f"{platform.system()} {platform.release()}.",
        f"- Python {platform.python_version()}; {', '.join(libs)}.",
        f"- Load average (1 / 5 / 15 min) at the start: {load_start}; at the end: {load_end}. "
        "Figures taken under load are disturbed: compare figures from one run only (the scale part's "
        "100 agent processes raise the load themselves at the end).",
    ]


def condition_lines(conditions: list[str], settle_s: float) -> list[str]:
    """The header's lines on how busy the machine was around the timed parts
    (services/bench/quiet.py)."""
    how = (
        f"Before each timed part `roco bench` waited up to {settle_s:.0f} s for a quiet machine "
        f"({quiet_rule()}, /proc/stat)"
        if settle_s > 0
        else "The machine's quiet was not waited for (`--settle 0`)"
    )
    if not conditions:  # no timed part ran
        return [] if settle_s > 0 else [f"- {how}."]
    return [
        f"- {how}; CPU time stolen by the hypervisor while a part ran (its noise):",
        *(f"  - {c}" for c in conditions),
    ]


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


def codec_table(rows: list[CodecRow]) -> list[str]:
    return _table(
        ["content", "encoded communicate", "encode µs", "decode µs", "calls per batch"],
        [
            [r.label, f"{r.encoded_bytes:,} B", f"{r.encode_us:.2f}", f"{r.decode_us:.2f}", str(r.calls)]
            for r in rows
        ],
    )


def _rate(x: float) -> str:
    return f"{x:,.0f}"


def _latency_cells(samples_s: Sequence[float]) -> list[str]:
    """p50, p90 and p99 (µs, nearest rank) and the count of round-trip samples (s)."""
    return [*(f"{percentile(samples_s, q) * 1e6:.0f}" for q in (50, 90, 99)), str(len(samples_s))]


def _stream_cells(t: Throughput) -> list[str]:
    """A stream's median rate, each run's rate and the communicates it lost."""
    return [_rate(t.median), ", ".join(_rate(x) for x in t.rates), str(t.lost)]


NO_RT = ["—"] * 4
NO_STREAM = ["—"] * 3


def link_label(secure: bool, links: str) -> str:
    """The link column: the security and the path of a testbed (services/bench/messaging.py)."""
    path = "one hop" if links == "peer" else "via the router"
    return f"mutual TLS + ACL, {path}" if secure else f"TCP, no ACL, {path}"


def _pair_rows(f: PairFigures, link: str, size: int) -> list[list[str]]:
    """One testbed's rows: roco one communicate per put; raw Zenoh polling, then sleeping (its
    stream on the first of them); roco's stream batched."""
    rows = [
        [
            f"roco (Agent runtime, {size} B content; stream: one communicate per put)",
            link,
            *_latency_cells(f.roco_rt.samples_s),
            *_stream_cells(f.roco_tput_single),
        ]
    ]
    raw = f"raw Zenoh ({request_bytes(size)} B payload, one per put)"
    raw_rows: list[tuple[str, Latency]] = []
    if f.raw_poll_rt.samples_s:
        raw_rows.append((f"{raw}, each end polling as roco's (≤ {f.poll_us:.0f} µs)", f.raw_poll_rt))
    raw_rows.append((f"{raw}, each end sleeping in `recv()`", f.raw_rt))
    for i, (label, latency) in enumerate(raw_rows):
        stream = _stream_cells(f.raw_tput) if i == 0 else NO_STREAM
        rows.append([label, link, *_latency_cells(latency.samples_s), *stream])
    rows.append(
        [
            f"roco, stream batched: the {STREAM_BATCH} informs of a step in one put",
            link,
            *NO_RT,
            *_stream_cells(f.roco_tput),
        ]
    )
    return rows


def _platform_row(label: str, link: str, other: SpadeFigures | JadeFigures) -> list[str]:
    """SPADE's or JADE's row: its round trips, its one stream's rate, what it did not deliver."""
    lost = str(max(0, other.sent - other.count))
    return [label, link, *_latency_cells(other.samples_s), _rate(other.rate), _rate(other.rate), lost]


def messaging_table(
    f: MessagingFigures | None, spade: SpadeFigures | None, jade: JadeFigures | None, size: int
) -> list[str]:
    """Parts 2, 3 and 3b side by side: roco and raw Zenoh with access control and mutual TLS,
    then both without, then SPADE and JADE (each when measured)."""
    rows = []
    if f is not None:
        rows += _pair_rows(f.secure, link_label(True, f.links), size)
        rows += _pair_rows(f.open, link_label(False, f.links), size)
    if spade is not None and not spade.error:
        label = f"SPADE {spade.versions.get('spade', '?')} over its XMPP server ({size}-character body)"
        rows.append(_platform_row(label, "TCP, no TLS, via the XMPP server", spade))
    if jade is not None and jade.samples_s:
        version = jade.versions.get("jade", "?")
        label = f"JADE {version}, two containers in two JVMs ({size}-character content)"
        rows.append(_platform_row(label, "IMTP over TCP, one hop", jade))
    if not rows:
        return []
    return _table(
        [
            "system",
            "link",
            "round trip p50 µs",
            "p90 µs",
            "p99 µs",
            "round trips",
            "stream /s (median)",
            "each run /s",
            "lost",
        ],
        rows,
    )


def spade_p50_us(spade: SpadeFigures) -> float:
    return percentile(spade.samples_s, 50) * 1e6


def _met(ok: bool) -> str:
    """A target's verdict word."""
    return "met" if ok else "missed"


def _dash(value: object, fmt: str = "{}") -> str:
    """``value`` formatted, or ``—`` when it was not measured (None)."""
    return "—" if value is None else fmt.format(value)


def _round_trip_verdicts(f: MessagingFigures) -> list[str]:
    """roco's round trip against raw Zenoh's on the same link (both polling, access control and
    mutual TLS on), then against raw Zenoh sleeping, then what the security costs."""
    s, o = f.secure, f.open
    out = []
    if s.raw_poll_rt.samples_s and s.raw_poll_rt.p50_us:
        ratio = s.roco_rt.p50_us / s.raw_poll_rt.p50_us
        out.append(
            f"- roco round trip / raw Zenoh's on the same link, both polling for up to {s.poll_us:.0f} µs "
            f"before sleeping, access control and mutual TLS on (p50): **{ratio:.2f}×** "
            f"({s.roco_rt.p50_us:.0f} against {s.raw_poll_rt.p50_us:.0f} µs; target ≤ {TARGET_RT_RATIO}×): "
            f"{_met(ratio <= TARGET_RT_RATIO)}."
        )
    if s.raw_rt.p50_us:
        sleeping = s.roco_rt.p50_us / s.raw_rt.p50_us
        who = "roco's receiving threads polling" if s.poll_us > 0 else "roco's receiving threads sleeping too"
        out.append(
            f"- Against raw Zenoh's ends sleeping in `recv()` on the same link ({who}): "
            f"**{sleeping:.2f}×** ({s.raw_rt.p50_us:.0f} µs)."
        )
    if o.roco_rt.p50_us:
        extra = (s.roco_rt.p50_us / o.roco_rt.p50_us - 1) * 100
        out.append(
            f"- Access control and mutual TLS: roco's round trip {s.roco_rt.p50_us:.0f} µs with them, "
            f"{o.roco_rt.p50_us:.0f} µs without (**{extra:+.0f} %**); its stream "
            f"{_rate(s.roco_tput_single.median)} against {_rate(o.roco_tput_single.median)} /s."
        )
    return out


def _throughput_verdict(f: MessagingFigures) -> str:
    """One pair's one-way stream, one communicate per put, against the target and raw Zenoh's."""
    s = f.secure
    tput = s.roco_tput_single.median
    share = tput / s.raw_tput.median * 100 if s.raw_tput.median else 0.0
    return (
        f"- roco one-way stream, one pair, one communicate per put, {f.size} B content, access control "
        f"and mutual TLS on: **{_rate(tput)} /s** (target ≥ {_rate(TARGET_TPUT)} /s): "
        f"{_met(tput >= TARGET_TPUT)}; {share:.1f} % of raw Zenoh's one payload per put on the same "
        f"link; batched (the {STREAM_BATCH} informs of a step in one put): {_rate(s.roco_tput.median)} /s."
    )


def _spade_verdict(f: MessagingFigures, spade: SpadeFigures) -> str:
    """roco against SPADE, both without TLS or access control: round trip and throughput (one
    communicate per put)."""
    o = f.open
    rt = spade_p50_us(spade) / o.roco_rt.p50_us if o.roco_rt.p50_us else 0.0
    tp = o.roco_tput_single.median / spade.rate if spade.rate else 0.0
    return (
        f"- Against SPADE, neither with TLS or access control, roco one communicate per put: round "
        f"trip **{rt:.1f}× faster** (target ≥ {TARGET_SPADE_RT}×): {_met(rt >= TARGET_SPADE_RT)}; "
        f"throughput **{tp:.1f}× higher** (target ≥ {TARGET_SPADE_TPUT}×): {_met(tp >= TARGET_SPADE_TPUT)}."
    )


def _task_row(r: TaskRun) -> list[str]:
    """One task run's row of ``task_table``; its loop's cells ``—`` when it has no timing."""
    t = r.timing
    loop = (
        ["—"] * 4
        if t is None
        else [
            str(t.cycles),
            f"{t.compute_p50_us:.0f} / {t.compute_p99_us:.0f} / {t.compute_max_us:.0f}",
            f"{t.lateness_p99_us:.0f}",
            f"{t.overruns} ({t.overrun_share * 100:.2f} %)",
        ]
    )
    return [
        r.pacing,
        "succeeded" if r.ok else f"failed: {r.detail[:120]}",
        f"{r.command_s:.1f}",
        _dash(r.task_s, "{:.1f}"),
        _dash(r.sim_time_s, "{:.1f}"),
        _dash(r.communicates),
        *loop,
        _dash(None if r.km_store_bytes is None else r.km_store_bytes / 1024, "{:.0f} KiB"),
    ]


def _mib_totals(procs: dict[str, tuple[float, float]]) -> tuple[str, str]:
    """The VmRSS and PSS totals of ``procs``, in bold."""
    return f"**{sum(v[0] for v in procs.values()):.1f}**", f"**{sum(v[1] for v in procs.values()):.1f}**"


def _fleet_memory_row(name: str, fleet: dict[str, dict[str, tuple[float, float]]]) -> list[str]:
    """One process's VmRSS and PSS in each state, ``—`` where it did not run."""
    row = [name]
    for procs in fleet.values():
        rss, pss = procs.get(name, (None, None))
        row += ["—", "—"] if rss is None or pss is None else [f"{rss:.1f}", f"{pss:.1f}"]
    return row


def _fleet_memory_table(fleet: dict[str, dict[str, tuple[float, float]]]) -> list[str]:
    """``roco up``'s fleet: one VmRSS and one PSS column per measured state, ``—`` where a
    process did not run, and the totals."""
    names = list(dict.fromkeys(name for procs in fleet.values() for name in procs))
    header = ["`roco up`'s fleet"]
    for state in fleet:
        label = state.removeprefix("fleet").lstrip(", ").strip() or state
        header += [f"{label}: VmRSS MiB", "PSS MiB"]
    rows = [_fleet_memory_row(name, fleet) for name in names]
    rows.append(["**total**", *(cell for procs in fleet.values() for cell in _mib_totals(procs))])
    return _table(header, rows)


def _fleet_memory_verdict(fleet: dict[str, dict[str, tuple[float, float]]]) -> list[str]:
    """The fleet's PSS at rest against its target, the busy states' beside it; none unmeasured."""
    totals = {state: sum(pss for _, pss in procs.values()) for state, procs in fleet.items()}
    rest = totals.get("fleet at rest")
    if rest is None:
        return []
    busy = [
        f"with the {k.removeprefix('fleet, ')}: {v:.0f} MiB"
        for k, v in totals.items()
        if k != "fleet at rest"
    ]
    return [
        f"- `roco up`'s fleet in all, at rest: **{rest:.0f} MiB** PSS (target ≤ "
        f"{TARGET_FLEET_MIB:.0f} MiB): {_met(rest <= TARGET_FLEET_MIB)}"
        + (f"; {'; '.join(busy)}." if busy else ".")
    ]


def verdict_lines(f: MessagingFigures | None, spade: SpadeFigures | None) -> list[str]:
    """The messaging targets (round trip against raw Zenoh on the same link, one pair's stream,
    SPADE), each met or missed, with the measured ratio; and what the security costs."""
    out = []
    if f is not None and f.secure.raw_rt.samples_s:
        out += [*_round_trip_verdicts(f), _throughput_verdict(f)]
    if f is not None and spade is not None and not spade.error and spade.samples_s:
        out.append(_spade_verdict(f, spade))
    return out


def knowledge_table(rows: list[QueryRow]) -> list[str]:
    def ms(x: float | None) -> str:
        return "—" if x is None else f"{x:.3f}"

    return _table(
        ["query", "answer B", "in a_km p50 ms", "in a_km p99 ms", "over Zenoh p50 ms", "over Zenoh p99 ms"],
        [
            [
                r.label,
                str(r.answer_bytes) if r.answer_bytes else "—",
                ms(r.local_p50_ms),
                ms(r.local_p99_ms),
                ms(r.zenoh_p50_ms),
                ms(r.zenoh_p99_ms),
            ]
            for r in rows
        ],
    )


def planning_table(p: PlanningFigures | None, runs: list[TaskRun]) -> list[str]:
    rows = []
    if p is not None:
        for i, (wall, own, queries, leaves) in enumerate(p.repeated, 1):
            rows.append(
                [
                    f"plan #1, request {i} (a_km + a_pl only)",
                    f"{wall:.3f}",
                    f"{own:.3f}",
                    str(queries),
                    str(leaves),
                ]
            )
    for run in runs:
        for plan in run.plans:
            took = (
                f"{plan.received_t - plan.requested_t:.3f}"
                if plan.received_t is not None and plan.requested_t is not None
                else "—"
            )
            rows.append(
                [
                    f"plan #{plan.index} in the pour ({run.pacing})",
                    took,
                    "—" if plan.planning_time_s is None else f"{plan.planning_time_s:.3f}",
                    "—"
                    if plan.km_queries is None
                    else f"{plan.km_queries} ({plan.c4_count} C4 communicates)",
                    plan.outcome,
                ]
            )
    return _table(
        ["plan", "request → plan s (wall)", "a_pl planning time s", "a_km queries", "leaves / outcome"], rows
    )


def fleet_table(f: FleetFigures) -> list[str]:
    lines = _table(
        ["figure", "value"],
        [
            ["`roco up` wall time (start to exit)", f"{f.command_s:.2f} s"],
            [
                "agents started → all liveliness tokens (printed by `roco up`)",
                "—" if f.alive_s is None else f"{f.alive_s:.2f} s",
            ],
            ["VmRSS of these processes at `roco up`'s exit, summed", f"{sum(f.rss_mib.values()):.0f} MiB"],
        ],
    )
    lines += ["", *_table(["process", "VmRSS MiB"], [[n, f"{v:.0f}"] for n, v in f.rss_mib.items()])]
    if f.error:
        lines += ["", f"`roco up` problem: {f.error}: {f.output[-300:]}"]
    return lines


def task_table(runs: list[TaskRun]) -> list[str]:
    return _table(
        [
            "pacing",
            "outcome",
            "`roco run` wall s",
            "command → end s",
            "simulated s",
            "communicates",
            "loop cycles",
            "compute p50 / p99 / max µs",
            "lateness p99 µs",
            "overruns",
            "a_km store after the run",
        ],
        [_task_row(r) for r in runs],
    )


def _with_runs(figures: ConcurrentFigures) -> str:
    """The steady all-pairs rate, and each run's when it is the median of several."""
    runs = figures.steady_runs
    each = f" ({', '.join(_rate(x) for x in runs)})" if len(runs) > 1 else ""
    return _rate(figures.steady_per_s) + each


def scale_table(rows: list[ScaleRow]) -> list[str]:
    body = []
    for r in rows:
        p = r.pair
        ratio = p.roco_rt.p50_us / p.raw_rt.p50_us if p.raw_rt.p50_us else 0.0
        body.append(
            [
                str(r.agents),
                "2, meshed" if r.routers == 2 else "1",
                f"{r.start_s:.1f}",
                f"{r.rss_mib_total:,.0f}",
                f"{p.roco_rt.p50_us:.0f} / {p.roco_rt.p99_us:.0f}",
                f"{p.raw_rt.p50_us:.0f} / {p.raw_rt.p99_us:.0f}",
                f"{ratio:.2f}",
                _rate(p.roco_tput.median),
                _rate(p.raw_tput.median),
                f"{r.concurrent.latency.p50_us:.0f} / {r.concurrent.latency.p99_us:.0f}",
                _rate(r.concurrent.round_trips_per_s),
                _with_runs(r.concurrent),
                _with_runs(r.raw_concurrent) if r.raw_concurrent is not None else "—",
            ]
        )
    return _table(
        [
            "agent processes",
            "routers",
            "start s",
            "agents' RSS MiB",
            "one pair: roco RT p50 / p99 µs",
            "raw RT p50 / p99 µs",
            "roco / raw",
            "roco /s",
            "raw /s",
            "all pairs at once: RT p50 / p99 µs",
            "all pairs: round trips /s, first command → last result",
            "all pairs: round trips /s while every pair runs",
            "raw Zenoh, as many processes, all pairs: round trips /s while every pair runs",
        ],
        body,
    )


def scale_verdicts(rows: list[ScaleRow]) -> list[str]:
    """The scale target: the all-pairs rate of the most agents against the fewest's,
    taken while every pair runs (see ``ConcurrentFigures``), the first-command-to-last-result
    share beside it."""
    rows = [r for r in rows if r.routers == 1]
    if len(rows) < 2:
        return []
    few, most = min(rows, key=lambda r: r.agents), max(rows, key=lambda r: r.agents)
    if not few.concurrent.steady_per_s or not few.concurrent.round_trips_per_s:
        return []
    share = most.concurrent.steady_per_s / few.concurrent.steady_per_s
    wall = most.concurrent.round_trips_per_s / few.concurrent.round_trips_per_s
    raw = ""
    if most.raw_concurrent is not None and few.raw_concurrent is not None and few.raw_concurrent.steady_per_s:
        raw_share = most.raw_concurrent.steady_per_s / few.raw_concurrent.steady_per_s
        raw = (
            f"; raw Zenoh's own processes, measured the same way: {raw_share * 100:.0f} % "
            f"({_rate(most.raw_concurrent.steady_per_s)} against {_rate(few.raw_concurrent.steady_per_s)} /s)"
        )
    return [
        f"- {most.agents} agents, all pairs at once: **{share * 100:.1f} %** of the {few.agents}-agent "
        f"round trips /s while every pair runs (target ≥ {TARGET_SCALE_SHARE * 100:.0f} %): "
        f"{'met' if share >= TARGET_SCALE_SHARE else 'missed'}; from the first command to the last "
        f"result {wall * 100:.0f} %{raw}."
    ]


def memory_table(m: MemoryFigures) -> list[str]:
    """Two tables, each with its totals: the idle synthetic pair's processes; then ``roco up``'s
    fleet, one VmRSS and one PSS column per measured state (``—`` where a process did not run)."""
    pair = [[name, f"{rss:.1f}", f"{pss:.1f}"] for name, (rss, pss) in m.synthetic.items()]
    out = _table(
        ["idle synthetic pair", "VmRSS MiB", "PSS MiB"], [*pair, ["**total**", *_mib_totals(m.synthetic)]]
    )
    if not m.fleet:
        return out
    return [*out, "", *_fleet_memory_table(m.fleet)]


def memory_verdicts(m: MemoryFigures) -> list[str]:
    """An idle synthetic agent ≤ 35 MiB VmRSS; the fleet ≤ 350 MiB PSS in all, at rest (and,
    beside it, while ag_ex's camera process runs)."""
    agents = {n: v for n, v in m.synthetic.items() if n != "router"}
    out = []
    if agents:
        worst = max(rss for rss, _ in agents.values())
        out.append(
            f"- An idle synthetic agent: **{worst:.1f} MiB** VmRSS at most ({', '.join(sorted(agents))}; "
            f"target ≤ {TARGET_AGENT_MIB:.0f} MiB): {_met(worst <= TARGET_AGENT_MIB)}."
        )
    return out + _fleet_memory_verdict(m.fleet)


def plan_and_fleet_verdicts(planning: PlanningFigures | None, fleet: FleetFigures | None) -> list[str]:
    """Plan #1 ≤ 2 s of wall time; ``roco up`` to all agents alive ≤ 3 s."""
    out = []
    if planning is not None and planning.repeated:
        worst = max(r[0] for r in planning.repeated)
        out.append(
            f"- Plan #1 wall time (request → plan, a_km and a_pl processes): at most **{worst:.3f} s** over "
            f"{len(planning.repeated)} requests (target ≤ {TARGET_PLAN_1_S:.0f} s): "
            f"{'met' if worst <= TARGET_PLAN_1_S else 'missed'}."
        )
    if fleet is not None and not fleet.error:
        out.append(
            f"- `roco up` until every agent is alive (its start to its exit): **{fleet.command_s:.2f} s** "
            f"(target ≤ {TARGET_UP_S:.0f} s): {'met' if fleet.command_s <= TARGET_UP_S else 'missed'}."
        )
    return out


# ------------------------------------------------------------------------- the sections


def codec_how() -> list[str]:
    """How part 1 measures (shared/fipa_codec, in the process of ``roco bench``)."""
    return [
        "`encode` and `decode` (msgpack, strict decoding) of a `request` with every envelope "
        "parameter set and 200 B, 10 kB or 1 MB of content, in one process: a batch of calls timed "
        "with `time.perf_counter` over its calls; the median of 5 batches after a warm-up one.",
    ]


def codec_section(rows: list[CodecRow]) -> Section:
    return Section("1. Codec (`codec`)", codec_how(), codec_table(rows))


def _platform_how(name: str, other: SpadeFigures | JadeFigures | None, why: str, measured: str) -> list[str]:
    """The bullet of SPADE or JADE: its settings and versions, how it was timed (``measured``),
    and ``why`` it was not measured, if it was not; none when the part was not run."""
    if other is None:
        return []
    versions = ", ".join(f"{k} {v}" for k, v in other.versions.items())
    return [
        f"- **{name}**: {other.settings or f'see services/bench/{name.lower()}.py'}"
        + (f"; versions: {versions}" if versions else "")
        + f". {measured}"
        + (f" **Not measured: {why}**" if why else "")
    ]


def messaging_how(
    counts: Counts,
    spade: SpadeFigures | None,
    jade: JadeFigures | None = None,
    links: str | None = None,
) -> list[str]:
    """How parts 2, 3 and 3b measure: roco's synthetic pair and raw Zenoh on two testbeds (with
    and without security), and (when run) SPADE and JADE. ``links``: the path the pair took
    (``peer``/``router``; None: ``ROCO_LINKS`` now)."""
    peer = (links or links_setting()) == "peer"
    path = (
        "linked directly (Zenoh peers, `ROCO_LINKS=peer`: one hop), the router on a loopback port "
        "for discovery"
        if peer
        else "through one router on a loopback port (`ROCO_LINKS=router`: two hops)"
    )
    return [
        f"Four processes (spawn) {path}, on two testbeds in turn (services/bench/messaging.py): "
        "**mutual TLS + ACL**, as every fleet runs (credentials and the router's access control issued "
        "by `roco deploy`'s code from the benchmark's specification, the router on `tls/`, each "
        "process authenticating as itself with its certificate and password, each peer applying the "
        "ACL to its links), then **TCP, no ACL**. On each, roco and raw Zenoh share the router, the "
        "endpoint, the credentials' kind and the path: each roco row is compared with the raw rows "
        "of its own link.",
        "",
        "- **roco**: two synthetic agents, each a real `Agent` on a `ZenohTransport` under a "
        "specification built in code (the Robot Companion's `fipa-request` and `fipa-subscribe`), "
        f"{counts.content_bytes} B of content. Round trip: the initiator's `send` of a `request` until "
        "the participant's `inform` is in its input buffer. Stream: the participant answers a "
        "`subscribe` with informs, one communicate per Zenoh put (the headline, as JADE sends); the "
        f"batched row puts the {STREAM_BATCH} informs of one step in one put "
        "(shared/fipa_codec/batch.py). Rate: informs taken in, each decoded and checked, after the "
        "initiator's first step that took any, over the time from that step to its last.",
        "- **raw Zenoh**: two bare Zenoh processes configured as an agent's Zenoh (the same "
        "link: same router and endpoint, TLS certificate, password and ACL when on, same hops), "
        "putting on the keys a pair of agents would, which the ACL grants as it grants roco's; a "
        "payload as long as roco's request. Ping-pong with `put` and a subscriber's FIFO, each end "
        "polling as roco's receiving threads do (the target's reference), then sleeping in "
        "`recv()` as zenoh-python's examples do; stream: a publisher's `put` in a loop, one payload "
        "per put, counted from the FIFO by one thread as roco's inbox is read.",
        "- Checked before a figure is given: the pair's first round trips answered within "
        "20 s, each timed command's round trips counted, and the agents' counters after the run: "
        "every communicate one sent the other received (the ACL drops silently), as many as "
        "asked, none refused, not understood, failed or rejected; else the part fails.",
        f"- {counts.rounds} round(s) of all of these per testbed, {counts.round_trips} round trips each "
        f"(after 50 warm-up ones), {counts.communicates:,} communicates per stream; round trips "
        "pooled, stream rates the median of the rounds'. `lost`: sent, not delivered (congestion "
        "control BLOCK). SPADE and JADE run without TLS or access control: compare them with "
        "the **TCP, no ACL** rows.",
        *_platform_how(
            "SPADE",
            spade,
            spade.error if spade is not None else "",
            "Round trip: a request `Message` until the inform is received; stream: rate = "
            "(received − 1) / (last − first arrival) at the responder.",
        ),
        *_platform_how(
            "JADE",
            jade,
            (jade.error or jade.skipped) if jade is not None else "",
            "Round trip (services/bench/java/, `System.nanoTime`): the initiator's `send` of a "
            "`request` until `blockingReceive` returns the responder's `inform`; stream: the "
            "initiator `send`s the informs in a loop, one message each, the responder's cyclic "
            "behaviour takes them from its queue, rate = (received − 1) / (last − first arrival) "
            "at the responder.",
        ),
    ]


def messaging_section(
    f: MessagingFigures | None, spade: SpadeFigures | None, jade: JadeFigures | None, counts: Counts
) -> Section:
    return Section(
        "2–3. Messaging: roco, raw Zenoh, SPADE and JADE (`messaging`, `spade`, `jade`)",
        messaging_how(counts, spade, jade, f.links if f is not None else None),
        messaging_table(f, spade, jade, counts.content_bytes),
    )


def knowledge_how(store: str, counts: Counts) -> list[str]:
    """How part 4 measures: a_km's world model in process, then over Zenoh."""
    return [
        "The scene is `roco run`'s default kitchen (velma/model/kitchen.xml at rest, its poses as "
        "ag_ex's ground truth reads them, where a run's camera estimates them) in the inform a_ta "
        f"sends a_km for a first observation. In process: `WorldModel.answer` on a fresh on-disk "
        f"Oxigraph store holding it ({store}), {counts.km_timed} calls after 10 warm-up ones "
        "(scripts/bench_km.py). Over Zenoh: an a_km process given the scene as a_ta gives it (its C6 "
        "fipa-subscribe agreed, then informed), then the same queries as C4 `query-ref`s from a Zenoh "
        "client playing a_pl, from the put to the `inform-ref`'s arrival. The part prints no figure "
        "when a_km does not know the jar's and the bowl's poses, answers a query without an answer, or "
        "counts anything refused, not understood or against its protocol.",
    ]


def knowledge_section(rows: list[QueryRow], store: str, counts: Counts) -> Section:
    return Section(
        "4. Knowledge: a_km's answers (`knowledge`)", knowledge_how(store, counts), knowledge_table(rows)
    )


def planning_how() -> list[str]:
    """How part 5 measures: plan #1 alone, and the plans of part 7's pours."""
    return [
        "Plan #1 of pour(jar, bowl) requested repeatedly from a Zenoh client playing a_co, only a_km "
        "and a_pl running (scripts/bench_planning.py), from the request's put to the plan's arrival. "
        "a_km is given `roco run`'s default kitchen as a_ta gives it (its C6 fipa-subscribe agreed, "
        "then informed), and each timed plan is checked to be plan #1 of `roco run`'s pour: the same "
        "leaf states and actions as a_pl makes in process for that kitchen (services/bench/plan_check.py; "
        "the leaves column counts them). The part prints no figure when a plan differs, when a_km does "
        "not know the scene, or when an agent counts anything refused, not understood or against its "
        "protocol. Then plans #1 and #2 of part 7's pours, from their run folders' reports (the last "
        f"column: their outcome). {PAPER_PLAN_1_TEXT}",
    ]


def planning_section(planning: PlanningFigures | None, runs: list[TaskRun]) -> Section:
    return Section(
        "5. Planning: plan #1 of the pour (`planning`)", planning_how(), planning_table(planning, runs)
    )


def fleet_how() -> list[str]:
    """How part 6 measures ``roco up``."""
    return [
        "`roco up --no-realtime` in a subprocess (router, recorder, six agents, access control on), "
        "from its start to its exit, and the time it prints from starting the agents to every "
        "liveliness token; VmRSS of each process it started, read at its exit (ag_ex's children "
        "left out: part 6b measures the fleet's memory); then `roco down`.",
    ]


def fleet_section(fleet: FleetFigures) -> Section:
    return Section("6. Fleet: `roco up` (`fleet`)", fleet_how(), fleet_table(fleet))


def memory_how() -> list[str]:
    """How part 6b measures resident memory (scripts/bench_memory.py)."""
    return [
        "scripts/bench_memory.py: an idle synthetic pair on a router of its own, then `roco up` "
        "with every process and child (ag_ex's `velma-loop` and `velma-camera`), each read once its "
        "VmRSS moved ≤ 0.25 MiB in 1 s: while ag_ex's camera process runs, then at rest once it has "
        "ended (`ROCO_CAMERA_IDLE_S`). PSS (/proc/PID/smaps_rollup) counts a page shared by n "
        "processes 1/n in each: its total is what the processes take in all.",
    ]


def memory_section(memory: MemoryFigures) -> Section:
    return Section(
        "6b. Memory: an idle agent and the fleet in all (`memory`)", memory_how(), memory_table(memory)
    )


def task_how() -> list[str]:
    """How part 7 measures the whole pour."""
    return [
        f'`roco run "{POUR}" --quiet`, headless, as fast as possible and (not with `--quick`) with '
        "`--realtime`; wall time timed here, the rest from the run folder. Loop: compute time of "
        "each 1 kHz cycle, lateness of its start, overruns (cycles ending after the next release; "
        "meaningless unpaced). a_km store: its directory's bytes after the run.",
    ]


def task_section(runs: list[TaskRun]) -> Section:
    return Section("7. Task: the whole pour (`task`)", task_how(), task_table(runs))


def scale_how(counts: Counts) -> list[str]:
    """How part 8 measures many agent processes on one router, then on two meshed."""
    return [
        "For each N: a fresh router, N synthetic agents (N/2 pairs) and a raw Zenoh pair, each a "
        "process; then on two meshed routers, every communicate crossing both. `start s`: first "
        "spawn to all ready. Then, before anything is timed, every pair's route is shown to exist "
        "(each initiator's request answered, sent at-least-once; each bare Zenoh publisher matched "
        "by its subscriber): a peer's liveliness can be known before its subscription's route, and "
        "a put in between is lost. After each all-pairs run every pair's exchange is checked as in "
        f"part 2. One pair: as in part 2 ({counts.scale_round_trips} round trips, "
        f"{counts.scale_communicates:,} communicates), the other agents idle. All pairs at once: "
        f"{counts.scale_all_pairs} round trips per initiator after 50 warm-up ones, "
        f"{counts.scale_all_rounds} time(s), the median run shown (each run's rate in brackets); "
        "rates over first command → last result, and over the window where every pair runs. Last "
        "column: N bare Zenoh processes (sleeping in `recv()`) measured the same way. RSS: the "
        "agents' VmRSS summed.",
    ]


def scale_section(rows: list[ScaleRow], counts: Counts) -> Section:
    return Section(
        "8. Scale: many agent processes sharing the router (`scale`)", scale_how(counts), scale_table(rows)
    )


def gateway_table(g: GatewayFigures) -> list[str]:
    load, burst = g.load, g.burst
    lines = _table(
        ["figure", "value"],
        [
            [
                f"{load.peers} peers at once, {load.messages} messages each: accepted /s",
                f"{load.per_s:,.0f} ({load.accepted} of {load.peers * load.messages} answered 200)",
            ],
            [
                "the same: one post, connect → status line, p50 / p99",
                f"{load.p50_ms:.0f} / {load.p99_ms:.0f} ms",
            ],
            [
                f"{burst.peers} peers posting at the same moment: answered 200",
                f"{burst.answered} of {burst.peers}, the last after {burst.last_s:.2f} s",
            ],
            [
                "the gateway's VmRSS after them; its peak under the worst requests",
                f"{g.rss_mib:.0f} MiB; {g.peak_mib:.0f} MiB",
            ],
        ],
    )
    rows = [
        [
            r.name,
            str(r.status) + ("" if r.status == r.expected else f" (expected {r.expected})"),
            f"{r.rss_growth_mib:.1f}",
            f"{r.cpu_s:.2f}",
        ]
        for r in g.worst
    ]
    header = ["worst request", "status", "peak RSS over RSS before, MiB", "CPU s (all of them)"]
    return [*lines, "", *_table(header, rows)]


def gateway_verdicts(g: GatewayFigures) -> list[str]:
    """500 peers at once all answered within 10 s; any one worst request ≤ 100 MiB of peak RSS
    growth and ≤ 1 s of CPU time."""
    burst = g.burst
    within = burst.answered == burst.peers and burst.last_s <= TARGET_GATEWAY_BURST_S
    rss = max((r.rss_growth_mib for r in g.worst), default=0.0)
    cpu = max((r.cpu_s / r.requests for r in g.worst), default=0.0)
    statuses = all(r.status == r.expected for r in g.worst)
    ok = rss <= TARGET_GATEWAY_RSS_MIB and cpu <= TARGET_GATEWAY_CPU_S and statuses
    burst_line = (
        f"- `roco gateway`, {burst.peers} peers posting at once: **{burst.answered} answered**, the "
        f"last after **{burst.last_s:.2f} s** (target: all within {TARGET_GATEWAY_BURST_S:.0f} s): "
        f"{'met' if within else 'missed'}."
    )
    worst_line = (
        f"- `roco gateway`, the worst requests (one at a time, and three at once): at most "
        f"**{rss:.0f} MiB** of peak RSS growth and **{cpu:.2f} s** of CPU a request (targets ≤ "
        f"{TARGET_GATEWAY_RSS_MIB:.0f} MiB, ≤ {TARGET_GATEWAY_CPU_S:.0f} s, each answered as expected): "
        f"{'met' if ok else 'missed'}."
    )
    return [burst_line, worst_line]


def gateway_how() -> list[str]:
    """How part 9 measures ``roco gateway`` (services/bench/gateway.py)."""
    return [
        "services/bench/gateway.py: a router with access control and `roco gateway` as a process of "
        "that fleet (no agents: what it forwards goes nowhere); peers on asyncio streams in the "
        "process of `roco bench` post requests as JADE 4.6 writes them, each peer a foreign agent "
        "of its own, a new connection per message (JADE's `Connection: close`). Load: the peers at "
        "once, each posting its messages one after the other; accepted /s = answers 200 over the "
        "wall time from the first connection to the last answer. Burst: every peer connects and "
        "posts at the same moment. Worst requests (what a hostile peer sends, bodies filling the "
        "8 MiB limit where size is the attack): each alone, then the three heaviest at once, each "
        "time followed by a valid message the gateway answers; peak RSS = VmHWM (reset through "
        "/proc/PID/clear_refs) over VmRSS before (memory an earlier request freed and the allocator "
        "kept is used again: a growth, not a use); CPU = user + system time of the gateway process "
        "(/proc/PID/stat) until that answer arrived. Before the worst requests the part checks the "
        "legitimate traffic (services/bench/gateway_check.py): every load and burst request answered "
        "200, the gateway's counters with as many received and forwarded and nothing refused or "
        "dropped, and each conversation delivered to a_hi's key once; else it gives no figure.",
    ]


def gateway_section(g: GatewayFigures) -> Section:
    return Section(
        "9. Gateway: `roco gateway` under load and attack (`gateway`)", gateway_how(), gateway_table(g)
    )


StopFigures = Any
"""scripts/bench_stop.py's ``StopFigures`` (the scripts directory is not a package)."""
ReadingRow = Any
"""scripts/bench_reading.py's ``ReadingRow``."""
STOP_CONDITIONS = {
    "plain": ("nothing", "alone"),
    "long line before": (
        "a {chars:,}-character {shape} line, {gap:.0f} ms earlier",
        "{gap:.0f} ms after a {chars:,}-character {shape} line",
    ),
}
"""What came before the stop, by bench_stop's condition: in the table, in the verdict."""
STOP_HOPS = {"C2": "a_hi's cancel (C2) ms", "C1": "a_co's (C1) ms", "C5": "a_ta's (C5) ms"}
"""The cancels a stop sends on its way to ag_ex's loop, by channel."""


def _stop_before(f: StopFigures, condition: str, in_verdict: bool = False) -> str:
    """What came before a stop of ``condition``."""
    labels = STOP_CONDITIONS.get(condition, (condition, condition))
    return labels[in_verdict].format(chars=f.long_chars, shape=f"`{f.long_shape}`", gap=f.gap_ms)


def _ms(x: float | None) -> str:
    return "—" if x is None else f"{x:.1f}"


def stop_table(f: StopFigures) -> list[str]:
    """Per condition: the halts, their p50 / p99 / max, the stops that found no motion, and the
    median of each hop."""
    hops = list(dict.fromkeys(h for per in f.hops_ms.values() for h in per))
    rows = []
    for condition, ms in f.halts_ms.items():
        rows.append(
            [
                _stop_before(f, condition),
                str(len(ms)),
                _ms(statistics.median(ms) if ms else None),
                _ms(f.percentile_ms(condition, 0.99)),
                _ms(max(ms) if ms else None),
                str(f.idle.get(condition, 0)),
                *(_ms(f.hops_ms[condition].get(h)) for h in hops),
            ]
        )
    header = ["before the stop", "halts", "p50 ms", "p99 ms", "max ms", "stops with no motion to halt"]
    return _table([*header, *(STOP_HOPS.get(h, f"{h} ms") for h in hops)], rows)


def stop_how(f: StopFigures) -> list[str]:
    """How part 10 measures a stop (scripts/bench_stop.py)."""
    pacing = "paced to wall time" if f.realtime else "as fast as it can"
    return [
        "scripts/bench_stop.py: a fleet as `roco run` starts it (router, recorder, six agents, access "
        f"control on), ag_ex's loop {pacing}; one whole pour first ({f.first_pour} in "
        f"{f.first_pour_s:.1f} s), then pours each stopped at a random moment, U(0.3, "
        f'{f.window_s:.0f}) s after a_co\'s agreement: by "stop" alone, or {f.gap_ms:.0f} ms after a '
        f"{f.long_chars:,}-character `{f.long_shape}` line (a shape of part 11), in turn until each has "
        f'{f.asked} halts. Timed on one wall clock from the put of "stop" on a_hi\'s key (the hop '
        "on to a_hi counted) to the wall time ag_ex's loop logs in the cycle the halt replaced "
        "the running command. A stop finding nothing moving has no halt: it is counted apart and "
        "another pour started. A pour that ran to its end empties the jar, which a_km then refuses "
        "to plan pouring, and stopped again and again the robot may leave the jar where it cannot "
        "take it: after the whole pour, a pour that failed or succeeded, or three stops in a row "
        "with nothing moving, a new "
        f"fleet starts from a fresh kitchen ({f.kitchens} in this run). The cancels' columns: "
        "the median ms from the put to a subscriber in "
        "`roco bench` seeing each cancel on its way, over the stops that halted.",
    ]


def stop_section(f: StopFigures) -> Section:
    return Section("10. A stop, from the line to the halt (`stop`)", stop_how(f), stop_table(f))


def stop_verdicts(f: StopFigures) -> list[str]:
    """A stop halts the commanded motion within 250 ms p99 of reaching a_hi, whatever came before
    it: met when every condition's p99 is within and it has the halts asked for."""
    said, ok = [], True
    for condition, ms in f.halts_ms.items():
        p99 = f.percentile_ms(condition, 0.99)
        enough = len(ms) >= f.asked
        ok = ok and enough and p99 is not None and p99 <= TARGET_STOP_P99_MS
        over = f"over {len(ms)} halts" if enough else f"over only {len(ms)} of the {f.asked} halts asked"
        figure = "no halt" if p99 is None else f"**{p99:.1f} ms** {over}"
        said.append(f"{_stop_before(f, condition, in_verdict=True)}: {figure}")
    if not said:
        return []
    return [
        f"- A stop halts the commanded motion within {TARGET_STOP_P99_MS:.0f} ms p99 of reaching a_hi, "
        f"whatever came before it: {'; '.join(said)} (target ≤ {TARGET_STOP_P99_MS:.0f} ms p99, "
        f"{f.asked} halts each): {'met' if ok else 'missed'}."
    ]


def reading_table(rows: Sequence[ReadingRow]) -> list[str]:
    return _table(
        ["shape", "characters", "p50 ms", "p99 ms", "stop check's look-ups", "what a_hi did"],
        [
            [r.shape, f"{r.chars:,}", f"{r.p50_ms:.3f}", f"{r.p99_ms:.3f}", str(r.lookups), r.answer]
            for r in rows
        ],
    )


def reading_how(counts: Counts) -> list[str]:
    """How part 11 measures a_hi's reading (scripts/bench_reading.py)."""
    return [
        "scripts/bench_reading.py, in the process of `roco bench`: a_hi on an in-memory bus (no a_co, "
        "no a_km: lines read at once with the kitchen's words), given lines of five shapes cut at a "
        'word to each length: `command` ("please please … pour the jar into the bowl": the run of '
        '"please" is one token), `polite` ("please robot please robot … pour the jar into the '
        'bowl": a token per word, parsed in full up to the 48-token bound, the slowest line read; '
        'past it refused unparsed), `words` ("the jar is on the table and the bowl …", not '
        "understood at its second sentence, or refused past the token bound), `stop` (the same "
        'words ending "oh no, stop!"), `typo` ("please … pour the jar itno the bowl": corrected and '
        "read again). Timed with "
        "`time.perf_counter` from the line's arrival to what a_hi does with it: the stop check; "
        f"within the {MAX_LINE_CHARS:,}-character bound, the parse in a_hi's reader thread (lark's "
        "Earley parser) and the request to a_co or the answer; beyond it, the refusal. "
        f"{counts.reading_repeats} lines per shape and length after 3 warm-up ones. Look-ups: the "
        "stop check's phrase look-ups, its work.",
    ]


def reading_section(rows: Sequence[ReadingRow], counts: Counts) -> Section:
    return Section(
        "11. a_hi's reading time against line length (`reading`)", reading_how(counts), reading_table(rows)
    )


def failed_section(errors: dict[str, str]) -> Section:
    """The parts that raised, with their errors (the other parts' figures stand)."""
    return Section("Parts that failed", [], [f"- {name}: {error}" for name, error in errors.items()])


# ------------------------------------------------------------------------- the document


def head(run_lines: Sequence[str]) -> list[str]:
    """The document's head: what it answers, then how the run was made (:func:`machine_lines`
    and :func:`condition_lines`)."""
    return [TITLE, "", *INTRO, "", RUN_TITLE, "", *run_lines, ""]


def targets_section(targets: Sequence[str]) -> Section:
    """The goals with their figures (:func:`verdict_lines` and the others), the missed beside
    the met: how many of each, then the lines with a missed target, then the others. A line
    without a verdict (a figure beside the one before it) stays with the line before it."""
    if not targets:
        return Section(TARGETS_TITLE, [TARGETS_INTRO], [NO_TARGETS])
    missed: list[str] = []
    met: list[str] = []
    group = met
    counts = {"met": 0, "missed": 0}
    for line in targets:
        words = VERDICT.findall(line)
        for w in words:
            counts[w] += 1
        if words:
            group = missed if "missed" in words else met
        group.append(line)
    table = [*([MISSED, "", *missed, ""] if missed else []), *([MET, "", *met] if met else [])]
    return Section(
        TARGETS_TITLE,
        [f"{TARGETS_INTRO} **{counts['missed']} missed**, {counts['met']} met."],
        table[:-1] if table[-1] == "" else table,
    )


def document(
    run_lines: Sequence[str], targets: Sequence[str], sections: Sequence[Section], notes: str
) -> str:
    """docs/benchmarks.md: the head, the targets (missed and met), the parts' sections in order,
    then ``notes`` (the hand-written method, services/bench/notes.md) when not empty."""
    body = "\n".join("\n".join(s.lines()) for s in [targets_section(targets), *sections])
    return "\n".join(head(run_lines)) + "\n" + body + ("\n" + notes if notes else "")
