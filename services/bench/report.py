"""Markdown tables of ``roco bench`` (docs/benchmarks.md) and the machine description."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from services.bench.messaging import ConcurrentFigures, PairFigures, ScaleRow, request_bytes
from services.bench.parts import CodecRow, FleetFigures, MemoryFigures, PlanningFigures, QueryRow, TaskRun
from services.bench.quiet import quiet_rule
from services.bench.spade import SpadeFigures

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("eclipse-zenoh", "msgspec", "mujoco", "pin", "pyoxigraph", "gtpyhop-core")
TARGET_RT_RATIO = 1.3
TARGET_TPUT = 50_000.0
TARGET_SPADE_RT = 3.0
TARGET_SPADE_TPUT = 10.0
TARGET_SCALE_SHARE = 0.6
"""Issue 20: the most agents' all-pairs rate over the fewest's (100 against 10)."""
TARGET_PLAN_1_S = 2.0
TARGET_AGENT_MIB = 35.0
"""Issue 20: an idle synthetic agent's VmRSS."""
TARGET_FLEET_MIB = 350.0
"""Issue 20: ``roco up``'s fleet in all (the sum of its processes' PSS, at rest)."""
TARGET_UP_S = 3.0


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


def messaging_table(f: PairFigures, spade: SpadeFigures | None, size: int) -> list[str]:
    """Part 2 and 3 side by side: raw Zenoh, roco, SPADE."""
    rows = [
        [
            f"raw Zenoh (put/subscriber, {request_bytes(size)} B payload)",
            f"{f.raw_rt.p50_us:.0f}",
            f"{f.raw_rt.p99_us:.0f}",
            str(len(f.raw_rt.samples_s)),
            _rate(f.raw_tput.median),
            ", ".join(_rate(x) for x in f.raw_tput.rates),
            str(f.raw_tput.lost),
        ],
    ]
    if f.raw_poll_rt.samples_s:
        rows.append(
            [
                f"raw Zenoh, each end polling as roco's receiving threads (≤ {f.poll_us:.0f} µs)",
                f"{f.raw_poll_rt.p50_us:.0f}",
                f"{f.raw_poll_rt.p99_us:.0f}",
                str(len(f.raw_poll_rt.samples_s)),
                "—",
                "—",
                "—",
            ]
        )
    rows += [
        [
            f"roco (Agent runtime, {size} B content)",
            f"{f.roco_rt.p50_us:.0f}",
            f"{f.roco_rt.p99_us:.0f}",
            str(len(f.roco_rt.samples_s)),
            _rate(f.roco_tput.median),
            ", ".join(_rate(x) for x in f.roco_tput.rates),
            str(f.roco_tput.lost),
        ],
    ]
    if f.roco_tput_single.runs:
        rows.append(
            [
                "roco, each communicate in a put of its own (no batches)",
                "—",
                "—",
                "—",
                _rate(f.roco_tput_single.median),
                ", ".join(_rate(x) for x in f.roco_tput_single.rates),
                str(f.roco_tput_single.lost),
            ]
        )
    if spade is not None and not spade.error:
        s_rt = sorted(spade.samples_s)
        p50 = s_rt[len(s_rt) // 2] * 1e6 if s_rt else 0.0
        p99 = s_rt[min(len(s_rt) - 1, round(0.99 * (len(s_rt) - 1)))] * 1e6 if s_rt else 0.0
        rows.append(
            [
                f"SPADE {spade.versions.get('spade', '?')} over its XMPP server ({size}-character body)",
                f"{p50:.0f}",
                f"{p99:.0f}",
                str(len(spade.samples_s)),
                _rate(spade.rate),
                _rate(spade.rate),
                str(max(0, spade.sent - spade.count)),
            ]
        )
    return _table(
        [
            "system",
            "round trip p50 µs",
            "p99 µs",
            "round trips",
            "throughput /s (median)",
            "each run /s",
            "lost",
        ],
        rows,
    )


def spade_p50_us(spade: SpadeFigures) -> float:
    s = sorted(spade.samples_s)
    return s[len(s) // 2] * 1e6 if s else 0.0


def verdict_lines(f: PairFigures | None, spade: SpadeFigures | None) -> list[str]:
    """The messaging targets of issue 9, each met or missed, with the measured ratio."""
    out = []
    if f is not None and f.raw_rt.samples_s:
        ratio = f.roco_rt.p50_us / f.raw_rt.p50_us if f.raw_rt.p50_us else float("inf")
        polling = (
            f"roco's receiving threads poll for up to {f.poll_us:.0f} µs before sleeping "
            "(services/runtime/polling.py), raw Zenoh's ends sleep in `recv()`"
            if f.poll_us > 0
            else "both sleep in a blocking receive (`ROCO_RECEIVE_POLL_US=0`)"
        )
        out.append(
            f"- roco round trip / raw Zenoh round trip (p50): **{ratio:.2f}×** (target ≤ "
            f"{TARGET_RT_RATIO}×): "
            f"{'met' if ratio <= TARGET_RT_RATIO else 'missed'}; {polling}."
        )
        if f.raw_poll_rt.samples_s and f.raw_poll_rt.p50_us:
            equal = f.roco_rt.p50_us / f.raw_poll_rt.p50_us
            out.append(
                f"- On equal terms, raw Zenoh's ends polling the same way: **{equal:.2f}×** "
                f"({f.roco_rt.p50_us:.0f} against {f.raw_poll_rt.p50_us:.0f} µs): what roco's "
                "runtime costs over the transport, wake-ups set aside."
            )
        tput = f.roco_tput.median
        out.append(
            f"- roco one-way throughput, one pair, 200 B content: **{_rate(tput)} /s** (target ≥ "
            f"{_rate(TARGET_TPUT)} /s): {'met' if tput >= TARGET_TPUT else 'missed'}; "
            f"{f.roco_tput.median / f.raw_tput.median * 100 if f.raw_tput.median else 0:.1f} % of raw "
            "Zenoh's"
            + (
                f"; each communicate in a put of its own (no batches): {_rate(f.roco_tput_single.median)} /s."
                if f.roco_tput_single.runs
                else "."
            )
        )
    if f is not None and spade is not None and not spade.error and spade.samples_s:
        rt = spade_p50_us(spade) / f.roco_rt.p50_us if f.roco_rt.p50_us else 0.0
        tp = f.roco_tput.median / spade.rate if spade.rate else 0.0
        out.append(
            f"- Against SPADE: round trip **{rt:.1f}× faster** (target ≥ {TARGET_SPADE_RT}×): "
            f"{'met' if rt >= TARGET_SPADE_RT else 'missed'}; throughput **{tp:.1f}× higher** "
            f"(target ≥ {TARGET_SPADE_TPUT}×): {'met' if tp >= TARGET_SPADE_TPUT else 'missed'}."
        )
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
    rows = []
    for r in runs:
        t = r.timing
        rows.append(
            [
                r.pacing,
                "succeeded" if r.ok else f"failed: {r.detail[:120]}",
                f"{r.command_s:.1f}",
                "—" if r.task_s is None else f"{r.task_s:.1f}",
                "—" if r.sim_time_s is None else f"{r.sim_time_s:.1f}",
                "—" if r.communicates is None else str(r.communicates),
                "—" if t is None else str(t.cycles),
                "—"
                if t is None
                else f"{t.compute_p50_us:.0f} / {t.compute_p99_us:.0f} / {t.compute_max_us:.0f}",
                "—" if t is None else f"{t.lateness_p99_us:.0f}",
                "—" if t is None else f"{t.overruns} ({t.overrun_share * 100:.2f} %)",
                "—" if r.km_store_bytes is None else f"{r.km_store_bytes / 1024:.0f} KiB",
            ]
        )
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
        rows,
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
    """Issue 20's scale target: the all-pairs rate of the most agents against the fewest's,
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
    """One row per process of each measured state, and each state's totals."""
    rows = []
    for state, procs in [("idle synthetic pair", m.synthetic), *m.fleet.items()]:
        for name, (rss, pss) in procs.items():
            rows.append([state, name, f"{rss:.1f}", f"{pss:.1f}"])
        total_rss, total_pss = sum(v[0] for v in procs.values()), sum(v[1] for v in procs.values())
        rows.append([state, "**total**", f"**{total_rss:.1f}**", f"**{total_pss:.1f}**"])
    return _table(["state", "process", "VmRSS MiB", "PSS MiB"], rows)


def memory_verdicts(m: MemoryFigures) -> list[str]:
    """An idle synthetic agent ≤ 35 MiB VmRSS; the fleet ≤ 350 MiB PSS in all, at rest (and,
    beside it, while ag_ex's camera process runs)."""
    agents = {n: v for n, v in m.synthetic.items() if n != "router"}
    out = []
    if agents:
        worst = max(rss for rss, _ in agents.values())
        out.append(
            f"- An idle synthetic agent: **{worst:.1f} MiB** VmRSS at most ({', '.join(sorted(agents))}; "
            f"target ≤ {TARGET_AGENT_MIB:.0f} MiB): {'met' if worst <= TARGET_AGENT_MIB else 'missed'}."
        )
    totals = {state: sum(pss for _, pss in procs.values()) for state, procs in m.fleet.items()}
    rest = totals.get("fleet at rest")
    if rest is not None:
        busy = [
            f"with the {k.removeprefix('fleet, ')}: {v:.0f} MiB"
            for k, v in totals.items()
            if k != "fleet at rest"
        ]
        out.append(
            f"- `roco up`'s fleet in all, at rest: **{rest:.0f} MiB** PSS (target ≤ "
            f"{TARGET_FLEET_MIB:.0f} MiB): {'met' if rest <= TARGET_FLEET_MIB else 'missed'}"
            + (f"; {'; '.join(busy)}." if busy else ".")
        )
    return out


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
            f"- `roco up` to all agents alive: **{fleet.command_s:.2f} s** from the command's start to its "
            f"exit once every agent's liveliness token is there (target ≤ {TARGET_UP_S:.0f} s): "
            f"{'met' if fleet.command_s <= TARGET_UP_S else 'missed'}."
        )
    return out
