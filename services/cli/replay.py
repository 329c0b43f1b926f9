"""``roco replay``: one agent of a recorded run again, compared with what it sent
(services/replay/driver.py)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import SpecFile, fail, run_folder
from services.spec.model import default_spec

if TYPE_CHECKING:
    from services.spec.model import SystemSpec

replay_app = typer.Typer()


@replay_app.command(short_help="Replay one agent of a recorded run and compare what it sends.")
def replay(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")],
    agent: Annotated[
        str | None,
        typer.Option("--agent", help="the agent to replay, as the specification names it (default: each)"),
    ] = None,
    most: Annotated[int, typer.Option(min=1, help="differences printed at most")] = 50,
    log: Annotated[bool, typer.Option("--log", help="print the replayed agent's log on stderr")] = False,
    spec: SpecFile = None,
) -> None:
    """Feed a fresh instance of AGENT, in this process, the communicates it received in the run,
    in causal order (an answer after what it answers, an answer to the agent after the agent has
    sent what it answers) and at the times they reached it, with every other agent a stub of the
    record, and compare what it sends with what it sent there: equal up to conversation-ids,
    reply-withs, times and fields read from a clock. One line per difference (the recorded
    communicate, the field, recorded and replayed). Without --agent, each agent of the
    specification (--spec, else the one the run used) in turn, one line each (an agent that
    cannot be replayed says why; one with a communicate of its own missing from the record says
    so, and one whose differences depend on an order the record leaves open says it cannot
    decide it). Exit 0 when equal, 1 with differences, an undecided order or a communicate
    missing, 2 when no replay can be made."""
    import logging

    from services.replay.driver import ReplayError, render
    from services.replay.driver import replay as replay_agent
    from services.runtime.run_folder import spec_for_run
    from services.spec.model import SpecError, load

    if log:
        logging.basicConfig(
            level=logging.INFO, stream=sys.stderr, format="%(name)s %(levelname)s %(message)s"
        )
    try:
        run = run_folder(run_dir)
        system = load(spec or spec_for_run(run))  # --spec, else the one the run used
        if agent is None:
            _replay_each(run, system)
            return
        result = replay_agent(run, agent, system)
    except (ReplayError, SpecError) as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(render(result, most))
    if not result.equal:
        raise typer.Exit(1)


def _replay_each(run_dir: Path, spec: SystemSpec | None) -> None:
    """``roco replay RUN``: each agent of ``spec`` replayed, one line each; exit 1 when one
    differs, 2 when none could be replayed."""
    from services.replay.driver import ReplayError, one_line
    from services.replay.driver import replay as replay_agent

    made = equal = 0
    for a in (spec or default_spec()).agents:
        try:
            result = replay_agent(run_dir, a.name, spec)
        except ReplayError as exc:
            typer.echo(f"{a.name}: not replayed: {exc}")
            continue
        made, equal = made + 1, equal + result.equal
        typer.echo(one_line(result))
    if not made:
        raise fail(f"no agent of {run_dir} could be replayed", code=2)
    if equal < made:
        raise typer.Exit(1)
