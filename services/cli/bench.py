"""`roco bench`: measure what roco costs on this machine, print each part's table, and write
them all to `docs/benchmarks.md` with the command, commit, machine and load.

Parts (`--only` takes a comma-separated subset; default all, in this order):

- `codec`: encoding and decoding one communicate of 200 B, 10 kB and 1 MB;
- `messaging`: round trip and one-way stream between two agents, and raw Zenoh's;
- `spade`: the same round trip and stream on SPADE, over XMPP;
- `jade`: the same round trip and stream on JADE, two containers in two JVMs, compiled from a
  JADE source tree (`--jade-home`; skipped, with one line saying what is missing, without a
  tree or a JDK);
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

A whole run (every part, full counts, none failed) to the default output also rewrites
README.md's figures table from docs/benchmarks.md and docs/bench/
(services/bench/readme_figures.py); any other run leaves README.md as it is.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from services.bench import quiet
from services.bench.runner import DEFAULT_OUT, PARTS
from shared.settings import Settings

bench_app = typer.Typer(
    add_completion=False,
    help=__doc__,
    short_help="Measure roco on this machine and write docs/benchmarks.md.",
    invoke_without_command=True,
    rich_markup_mode="markdown",
)


def _parts(only: str | None) -> list[str]:
    """The parts ``--only`` names, in ``PARTS``'s order (every part without it); an unknown
    one: a usage error naming the parts."""
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
    jade_home: Annotated[
        Path | None,
        typer.Option(
            help="a JADE source tree, compiled and measured by the jade part "
            f"[default: {Settings.env_name('jade_home')}; neither: the part is skipped]",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Run the benchmarks, print each table, write them to OUT (default docs/benchmarks.md)."""
    from services.bench.runner import run_bench

    if settle is None:
        settle = 0.0 if quick else quiet.DEFAULT_WAIT_S
    if settle < 0:
        raise typer.BadParameter(f"--settle {settle:g}: expected seconds ≥ 0 (0: do not wait)")

    chosen = _parts(only)
    args = " ".join(a for a in sys.argv[1:] if a != "bench")
    command = f"roco bench {args}".strip()
    if not run_bench(chosen, quick, settle, out, scale_agents, jade_home, command):
        raise typer.Exit(1)
