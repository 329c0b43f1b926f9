"""`roco bench`: every benchmark of issues 9 and 20 in one command, printed as tables and written to
`docs/benchmarks.md` with the machine, the versions, the load and the command.

Parts (`--only` takes a comma-separated subset; default all, in this order):
`codec`, `messaging` (roco against raw Zenoh), `spade` (the same tests on SPADE, run
right after `messaging`), `knowledge`, `planning`, `fleet`, `memory` (an idle agent's and the
fleet's resident memory), `task`, `scale`.
`--quick` shrinks every count (a smoke test of the command, not figures to quote).
A part that fails is reported in the document with its error; the others still run.
"""

from __future__ import annotations

import functools
import os
import shutil
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from services.bench import quiet

PARTS = ("codec", "messaging", "spade", "knowledge", "planning", "fleet", "memory", "task", "scale")
ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "docs" / "benchmarks.md"

bench_app = typer.Typer(
    add_completion=False,
    help=__doc__,
    short_help="Every benchmark of issues 9 and 20, printed and written to docs/benchmarks.md.",
    invoke_without_command=True,
    rich_markup_mode="markdown",
)


def _parts(only: str | None) -> list[str]:
    if not only:
        return list(PARTS)
    chosen = [p.strip() for p in only.split(",") if p.strip()]
    unknown = [p for p in chosen if p not in PARTS]
    if unknown:
        raise typer.BadParameter(f"unknown part(s) {', '.join(unknown)}; parts: {', '.join(PARTS)}")
    return [p for p in PARTS if p in chosen]


@bench_app.callback()
def bench(
    only: Annotated[str | None, typer.Option(help=f"comma-separated parts of: {', '.join(PARTS)}")] = None,
    quick: Annotated[
        bool, typer.Option(help="small counts: checks the command, figures not to quote")
    ] = False,
    out: Annotated[
        Path,
        typer.Option(
            help="the Markdown file written [default: docs/benchmarks.md of this checkout]",
            show_default=False,
        ),
    ] = DEFAULT_OUT,
    scale_agents: Annotated[
        str, typer.Option(help="agent process counts of the scale part, comma-separated")
    ] = "10,50,100",
    settle: Annotated[
        float | None,
        typer.Option(
            help="before each timed part, wait up to this many seconds for a quiet machine "
            f"({quiet.quiet_rule()}); 0: do not wait "
            f"[default: {quiet.DEFAULT_WAIT_S:.0f}; 0 with --quick]",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Run the benchmarks, print each table, write them to OUT (default docs/benchmarks.md)."""
    from services.bench import messaging, parts, report, spade

    if settle is None:
        settle = 0.0 if quick else quiet.DEFAULT_WAIT_S
    if settle < 0:
        raise typer.BadParameter(f"--settle {settle:g}: expected seconds ≥ 0 (0: do not wait)")

    chosen = _parts(only)
    started, t0, load_start = time.time(), time.perf_counter(), report.load()
    args = " ".join(a for a in sys.argv[1:] if a != "bench")
    command = f"roco bench {args}".strip()
    sections: list[str] = []
    targets: list[str] = []
    errors: dict[str, str] = {}
    results: dict[str, Any] = {}

    conditions: list[str] = []  # how busy the machine was before and during the timed parts

    def settled(label: str) -> None:
        if settle > 0:
            typer.echo(f"roco bench: waiting up to {settle:.0f} s for a quiet machine ({label})…", err=True)
            conditions.append(f"{label}: {quiet.settle(settle).text()}")

    def run(name: str, fn: Callable[[], Any], timed: bool = False) -> Any:
        if timed:
            settled(f"before {name}")
        typer.echo(f"roco bench: {name}…", err=True)
        t, cpu = time.perf_counter(), quiet.read() if timed else None
        try:
            results[name] = fn()
        except Exception as exc:  # one part failing must not lose the others
            errors[name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
            results[name] = None
        during = quiet.share(cpu, quiet.read()) if timed else None
        if during is not None:
            conditions.append(
                f"during {name}: {during.steal * 100:.1f} % of the CPU time stolen by the hypervisor"
            )
        typer.echo(f"roco bench: {name} done in {time.perf_counter() - t:.0f} s", err=True)
        return results[name]

    def emit(title: str, how: list[str], table: list[str]) -> None:
        block = [f"## {title}", "", *how, *([""] if how else []), *table, ""]
        typer.echo("\n".join(block))
        sections.append("\n".join(block))

    size = 200
    rt_n, tput_n, rounds = (300, 5000, 1) if quick else (2000, 50000, 3)
    if "codec" in chosen and run("codec", lambda: parts.codec(quick)) is not None:
        emit(
            "1. Codec",
            [
                "msgpack `encode`/`decode` of shared/fipa_codec (strict decoding: types, agent names, size "
                "limit) of a `request` communicate with sender, receiver, language, encoding, ontology, "
                "protocol, conversation-id, reply-with and reply-by set, and 200 B, 10 kB or 1 MB of "
                "content. "
                "Time per call: a batch of calls timed with `time.perf_counter` divided by its calls; the "
                "median of 5 batches after a warm-up batch.",
            ],
            report.codec_table(results["codec"]),
        )
    pair = None
    if "messaging" in chosen:
        got = run("messaging", lambda: messaging.messaging(rounds, rt_n, tput_n, size), timed=True)
        pair = got[0] if got else None
    sp = None
    if "spade" in chosen:
        sp = run(
            "spade", lambda: spade.measure(200 if quick else 1000, 1000 if quick else 5000, size), timed=True
        )
    if pair is not None or sp is not None:
        how = [
            "Between two processes on this host through one router on a free loopback port "
            "(`tcp/127.0.0.1:P`, the roco router process `services.runtime.router`, no multicast scouting, "
            "no access control), started with `multiprocessing` spawn (services/bench/messaging.py):",
            "",
            "- **roco**: two synthetic agents `b_ini0`/`b_par0`, each a real `Agent` "
            "(services/runtime/agent.py) "
            "on a `ZenohTransport`, specified by a synthetic specification built in code (one channel, the "
            "Robot "
            "Companion's `fipa-request` and `fipa-subscribe` definitions) and a content language `L_BENCH` "
            f"whose terms carry {size} B of content. Round trip: the initiator's `send` of a `request` (a "
            "new "
            "conversation each, `expect_reply`) until the participant's `inform` (echoing the content) is "
            "in the "
            "initiator's input buffer. Throughput: the initiator `subscribe`s; the participant `agree`s "
            "and sends "
            "the informs 256 per FSM step (so they travel in batches: one Zenoh put for what one step sends "
            "to one receiver, shared/fipa_codec/batch.py); counted where they reach the initiator's input "
            "buffer after decoding "
            "and validation, each checked on its own; each step of the initiator's behaviour that takes some "
            "in is stamped, and rate = (received − those of the first such step) / (last stamp − first "
            "stamp): what arrived before the first stamp is not counted in a span it did not take.",
            "- **raw Zenoh**: two bare Python sessions (same client configuration) through the same router: "
            "ping-pong with `put` and a subscriber's FIFO handler on each side; throughput with a declared "
            "publisher's `put` in a loop and a counting subscriber callback; the payload has the length of "
            "roco's encoded request communicate. The ping-pong runs twice: each end sleeping in `recv()` "
            "(issue 20's reference), then each end polling as roco's receiving threads do "
            "(services/runtime/polling.py: `try_recv` with `sched_yield` for an adaptive window, then "
            "`recv()`), the ratio on equal terms.",
            f"- Each of {rounds} round(s): raw ping-pong (sleeping, then polling), roco ping-pong, raw "
            "throughput, roco throughput, "
            f"{rt_n} round trips (after 50 warm-up ones) and {tput_n:,} communicates each; round trips are "
            "pooled over rounds; throughput is the median of the rounds. `lost`: sent but not delivered "
            "(both sides put with congestion control BLOCK, so nothing should be lost).",
        ]
        if sp is not None:
            how += [
                f"- **SPADE**: {sp.settings or 'see services/bench/spade.py'}"
                + (
                    f"; versions: {', '.join(f'{k} {v}' for k, v in sp.versions.items())}"
                    if sp.versions
                    else ""
                )
                + ". Round trip: `send` of a request `Message` until the inform is received; throughput: the "
                "responder counts messages, rate = (received − 1) / (last − first arrival)."
                + (f" **Not measured: {sp.error}**" if sp.error else ""),
            ]
        table = report.messaging_table(pair, sp, size) if pair is not None else []
        emit("2–3. Messaging: roco, raw Zenoh and SPADE, side by side", how, table)
        verdicts = report.verdict_lines(pair, sp)
        if verdicts:
            emit("Messaging targets", [], verdicts)
        targets.extend(verdicts)
    if "knowledge" in chosen and run("knowledge", lambda: parts.knowledge(quick)) is not None:
        rows, store = results["knowledge"]
        emit(
            "4. Knowledge (a_km)",
            [
                "In a_km: `WorldModel.answer` on a fresh on-disk Oxigraph store after the initial "
                "observation "
                f"({store}), 10 warm-up calls then {30 if quick else 200} timed "
                "(scripts/bench_km.py's timer). Over Zenoh: the same queries as C4 `query-ref`s (fipa-query, "
                "L_WM) from a session playing a_pl to a real a_km process through a router (no access "
                "control), "
                "timed from the put to the `inform-ref`'s arrival. The store size after a whole run is in "
                "part 7.",
            ],
            report.knowledge_table(rows),
        )
    task_runs: list[Any] = []
    if "task" in chosen:
        runs_dir = Path(tempfile.mkdtemp(prefix="roco-bench-runs-"))
        for realtime in (False,) if quick else (False, True):
            got = run(
                f"task{' (real time)' if realtime else ''}", functools.partial(parts.task, realtime, runs_dir)
            )
            if got is not None:
                task_runs.append(got)
    if "planning" in chosen:
        p = run("planning", lambda: parts.planning(quick))
        emit(
            "5. Planning",
            [
                "Plan #1 of pour(jar, bowl) requested repeatedly with only a_km and a_pl running "
                "(scripts/bench_planning.py's `measure`: router, a_km on its on-disk store given the "
                "scene, a "
                "session playing a_co; wall time from the request's put to the plan's arrival), and plans #1 "
                "and #2 of the whole pour of part 7 (its run folder's report: C3 request to a_pl's answer; "
                "the "
                f"plan's own planning time and a_km query count). {PAPER_PLAN_1_TEXT}",
            ],
            report.planning_table(p, task_runs),
        )
    if "fleet" in chosen and run("fleet", parts.fleet) is not None:
        emit(
            "6. Fleet",
            [
                "`roco up --port P --runs-dir TMP --no-realtime` in a subprocess (router, recorder, the "
                "six agents; "
                "access control as `roco up` does by default), timed from its start to its exit, and the "
                "time it "
                "prints from starting the agents to every liveliness token; then VmRSS "
                "(/proc/PID/status) of every process it started, read once at its exit; then `roco down`. "
                "Not the fleet's memory: ag_ex's loop and camera processes are not counted, a library "
                "shared by all is counted once per process, and ag_ex has not yet observed; part 6b "
                "measures that (PSS, children, at rest and while the camera runs).",
            ],
            report.fleet_table(results["fleet"]),
        )
    if "memory" in chosen and run("memory", parts.memory) is not None:
        emit(
            "6b. Memory: an idle agent and the fleet in all",
            [
                "`python scripts/bench_memory.py --only synthetic,fleet`, as imported here: an idle "
                "synthetic pair (part 2's agents, spawn) on a router of its own, and `roco up --port P "
                "--runs-dir TMP --no-realtime` (access control on) with every process it started and "
                "their children (ag_ex's `velma-loop` and `velma-camera`), each read once its VmRSS "
                "changed by ≤ 0.25 MiB over 1 s: first while ag_ex's camera process runs (it observes "
                "for a_km at start), then at rest once that process has ended (after "
                "`ROCO_CAMERA_IDLE_S` without an Observe); then `roco down`. VmRSS from "
                "/proc/PID/status; PSS from /proc/PID/smaps_rollup (a page shared by n processes "
                "counted 1/n in each, so PSS's total is what the processes take in all).",
            ],
            report.memory_table(results["memory"]),
        )
        targets.extend(report.memory_verdicts(results["memory"]))
    if task_runs:
        emit(
            "7. Task: the whole pour",
            [
                f'`roco run "{parts.POUR}" --quiet` in a subprocess, headless, as fast as possible and '
                "(not with "
                "`--quick`) with `--realtime`; `roco run` wall time timed here; command → end, simulated "
                "time, "
                "communicates and the loop statistics from the run folder (run.json, ag_ex_timing.json, the "
                "report). Loop: compute per 1 kHz cycle, lateness after its release, overruns (cycle ended "
                "after "
                "the next release; in the unpaced run the loop never waits, so overruns are not meaningful "
                "there). a_km store: bytes of the run folder's `km_store` directory after the run.",
            ],
            report.task_table(task_runs),
        )
    if "scale" in chosen:
        counts = [int(x) for x in scale_agents.split(",") if x.strip()]
        counts = counts[:1] if quick else counts
        s_rt, s_tput, s_all = (200, 5000, 50) if quick else (1000, 20000, 500)
        s_rounds = 1 if quick else 3
        rows = run(
            "scale",
            lambda: (
                messaging.scale(counts, s_rt, s_tput, s_all, size, all_rounds=s_rounds, before=settled)
                + messaging.scale(
                    counts, s_rt, s_tput, s_all, size, meshed=True, all_rounds=s_rounds, before=settled
                )
            ),
            timed=True,
        )
        if rows is not None:
            emit(
                "8. Scale: many agent processes sharing the router",
                [
                    "For each N: a fresh router, N synthetic agents (N/2 pairs, as in part 2) and one raw "
                    "Zenoh "
                    "pair, each a process (spawn); then the same on two routers meshed (the second "
                    "started with `--connect` to the first; initiators and the raw pinger on the first, "
                    "participants and the raw echo on the second: every communicate crosses both). "
                    "`start s`: from the first spawn until every process "
                    "reported ready (connected, subscribed, token declared). One pair: pair 0 measured as in "
                    f"part 2 ({s_rt} round trips, {s_tput:,} communicates, one round) while the other N − 2 "
                    "agents are connected and idle. All pairs at once: every initiator does "
                    f"{s_all} round trips (+50 warm-up) at the same time, {s_rounds} time(s) (the "
                    "median of the runs, each run's figure in brackets; latencies pooled); the rate is "
                    "all round trips "
                    "over the wall time from the first command to the last result, and the round trips "
                    "that ended while every pair was doing its measured ones over that window (from the "
                    "latest pair's first end to the earliest pair's last end: no start, no tail of the last "
                    "pairs finishing alone). Then, for the transport's own figure, N bare Zenoh processes "
                    "(N/2 raw ping-pong pairs, each end sleeping in `recv()`, a payload of roco's encoded "
                    "request's length) on a fresh router (or two meshed) do the same, every pair at once. "
                    "RSS: sum of the agents' VmRSS.",
                ],
                report.scale_table(rows),
            )
            targets.extend(report.scale_verdicts(rows))
    targets.extend(report.plan_and_fleet_verdicts(results.get("planning"), results.get("fleet")))
    if task_runs and all(r.ok for r in task_runs):
        shutil.rmtree(task_runs[0].run_dir.parent, ignore_errors=True)  # kept when a run failed
    if errors:
        emit("Parts that failed", [], [f"- {k}: {v}" for k, v in errors.items()])
    seconds = time.perf_counter() - t0
    head = [
        "# roco benchmarks",
        "",
        "Written by `roco bench` (services/bench/); every table below comes from the one command named here, "
        "run on the machine described here. Profiles and what was changed: the last section.",
        "",
        *report.machine_lines(command, load_start, report.load(), started, seconds),
        *report.condition_lines(conditions, settle),
        "",
        "## Targets of issues 9 and 20 in this run",
        "",
        *(targets or ["- (no part with a target was run)"]),
        "",
    ]
    notes = NOTES.read_text() if NOTES.exists() else ""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(head) + "\n" + "\n".join(sections) + ("\n" + notes if notes else ""))
    typer.echo("\n".join(["## Targets of issues 9 and 20 in this run", "", *targets, ""]))
    typer.echo(f"roco bench: wrote {out} in {seconds:.0f} s", err=True)
    if errors:
        raise typer.Exit(1)


PAPER_PLAN_1_TEXT = "The paper's plan #1 took 55 s and 1,598 communicates."
NOTES = Path(__file__).with_name("notes.md")
"""Hand-written findings (profiles, changes, gaps) appended to the generated document."""


def main() -> None:  # ``python -m services.bench.cli``
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    bench_app()


if __name__ == "__main__":
    main()
