"""`roco bench`: measure what roco costs on this machine, print each part's table, and write
them all to `docs/benchmarks.md` with the command, commit, machine and load.

Parts (`--only` takes a comma-separated subset; default all, in this order):

- `codec`: encoding and decoding one communicate of 200 B, 10 kB and 1 MB;
- `messaging`: round trip and one-way stream between two agents, and raw Zenoh's;
- `spade`: the same round trip and stream on SPADE, over XMPP;
- `knowledge`: a_km's answers to the planner's queries, in process and over Zenoh;
- `planning`: plan #1 of the pour, from the request to the plan;
- `fleet`: `roco up` until every agent is alive, and its processes' memory;
- `memory`: an idle agent's and the whole fleet's memory (VmRSS and PSS);
- `task`: the whole pour with `roco run`, and its 1 kHz loop;
- `scale`: 10 to 100 agent processes sharing one router, then two routers;
- `gateway`: `roco gateway` with 100 peers at once, 500 in one burst, and under the worst requests;
- `stop`: a stop's latency, from the line "stop" reaching a_hi to ag_ex's halt, with and without
  a long line before it;
- `reading`: a_hi's reading time against the length of a line.

Each timed part first waits for a quiet machine (`--settle`). `--quick` shrinks every count (a
smoke test of the command, not figures to quote). A part that fails is reported in the
document with its error; the others still run.
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

PARTS = (
    "codec",
    "messaging",
    "spade",
    "knowledge",
    "planning",
    "fleet",
    "memory",
    "task",
    "scale",
    "gateway",
    "stop",
    "reading",
)
ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "docs" / "benchmarks.md"

bench_app = typer.Typer(
    add_completion=False,
    help=__doc__,
    short_help="Measure roco on this machine and write docs/benchmarks.md.",
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
    counts = report.Counts.of(quick)
    started, t0, load_start = time.time(), time.perf_counter(), report.load()
    args = " ".join(a for a in sys.argv[1:] if a != "bench")
    command = f"roco bench {args}".strip()
    sections: list[report.Section] = []
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

    def emit(section: report.Section) -> None:
        typer.echo("\n".join(section.lines()))
        sections.append(section)

    n = counts
    if "codec" in chosen and run("codec", lambda: parts.codec(quick)) is not None:
        emit(report.codec_section(results["codec"]))
    pair = None
    if "messaging" in chosen:
        got = run(
            "messaging",
            lambda: messaging.messaging(n.rounds, n.round_trips, n.communicates, n.content_bytes),
            timed=True,
        )
        pair = got[0] if got else None
    sp = None
    if "spade" in chosen:
        sp = run(
            "spade",
            lambda: spade.measure(n.spade_round_trips, n.spade_messages, n.content_bytes),
            timed=True,
        )
    if pair is not None or sp is not None:
        emit(report.messaging_section(pair, sp, counts))
        targets.extend(report.verdict_lines(pair, sp))
    if "knowledge" in chosen and run("knowledge", lambda: parts.knowledge(quick)) is not None:
        rows, store = results["knowledge"]
        emit(report.knowledge_section(rows, store, counts))
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
        emit(report.planning_section(run("planning", lambda: parts.planning(quick)), task_runs))
    if "fleet" in chosen and run("fleet", parts.fleet) is not None:
        emit(report.fleet_section(results["fleet"]))
    if "memory" in chosen and run("memory", parts.memory) is not None:
        emit(report.memory_section(results["memory"]))
        targets.extend(report.memory_verdicts(results["memory"]))
    if task_runs:
        emit(report.task_section(task_runs))
    if "scale" in chosen:
        agent_counts = [int(x) for x in scale_agents.split(",") if x.strip()]
        agent_counts = agent_counts[:1] if quick else agent_counts
        rows = run(
            "scale",
            lambda: (
                messaging.scale(
                    agent_counts,
                    n.scale_round_trips,
                    n.scale_communicates,
                    n.scale_all_pairs,
                    n.content_bytes,
                    all_rounds=n.scale_all_rounds,
                    before=settled,
                )
                + messaging.scale(
                    agent_counts,
                    n.scale_round_trips,
                    n.scale_communicates,
                    n.scale_all_pairs,
                    n.content_bytes,
                    meshed=True,
                    all_rounds=n.scale_all_rounds,
                    before=settled,
                )
            ),
            timed=True,
        )
        if rows is not None:
            emit(report.scale_section(rows, counts))
            targets.extend(report.scale_verdicts(rows))
    if "gateway" in chosen:
        from services.bench import gateway

        got = run("gateway", lambda: gateway.measure(quick), timed=True)
        if got is not None:
            emit(report.gateway_section(got))
            targets.extend(report.gateway_verdicts(got))
    if "stop" in chosen:
        got = run("stop", lambda: parts.stop(n.stops), timed=True)
        if got is not None:
            emit(report.stop_section(got))
            targets.extend(report.stop_verdicts(got))
    if "reading" in chosen and run("reading", lambda: parts.reading(n.reading_repeats)) is not None:
        emit(report.reading_section(results["reading"], counts))
    targets.extend(report.plan_and_fleet_verdicts(results.get("planning"), results.get("fleet")))
    if task_runs and all(r.ok for r in task_runs):
        shutil.rmtree(task_runs[0].run_dir.parent, ignore_errors=True)  # kept when a run failed
    if errors:
        emit(report.failed_section(errors))
    seconds = time.perf_counter() - t0
    run_lines = [
        *report.machine_lines(command, load_start, report.load(), started, seconds),
        *report.condition_lines(conditions, settle),
    ]
    notes = NOTES.read_text() if NOTES.exists() else ""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(report.document(run_lines, targets, sections, notes))
    typer.echo("\n".join(report.targets_section(targets).lines()))
    typer.echo(f"roco bench: wrote {out} in {seconds:.0f} s", err=True)
    if errors:
        raise typer.Exit(1)


NOTES = Path(__file__).with_name("notes.md")
"""The hand-written "Method and where the time goes" appended to the generated document."""


def main() -> None:  # ``python -m services.bench.cli``
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    bench_app()


if __name__ == "__main__":
    main()
