"""``roco report``: a run's report with its requirements traced (services/report/,
services/spec_check/trace.py), and the report and the one-line outcome a run ends with."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli_common import INTERRUPTED, SpecFile, chosen_spec, fail, run_folder
from services.runtime.run_folder import RunInfo
from shared.settings import Settings

if TYPE_CHECKING:
    from services.report.model import ContentOutcome, CoverageSummary

report_app = typer.Typer()


def finish_report(run_dir: Path, info: RunInfo, *, interrupted: bool = False) -> None:
    """Write the run's report and say in one line how the run went; when ``interrupted``
    (Ctrl-C, SIGTERM, SIGHUP: the runner stopped the fleet), say only that, and exit 130."""
    from services.report import build_report, write_report
    from services.spec_check.trace import report_rows

    try:
        path = write_report(run_dir, coverage=_coverage_summary(run_dir), tracer=report_rows)
        report = build_report(run_dir)
    except Exception as exc:  # the run's outcome stands even if its report cannot be made
        if interrupted:
            raise fail(f"interrupted; the fleet is stopped; run folder {run_dir}", INTERRUPTED) from None
        typer.echo(f"roco: report not written: {exc}", err=True)
        return
    if interrupted:
        raise fail(f"interrupted; the fleet is stopped; report {path}", INTERRUPTED)
    share = _content_clause(run_dir, info, report.content)
    typer.echo(
        f"roco: {'succeeded' if info.succeeded else 'failed'} in {info.ended - info.started:.1f} s wall; "  # type: ignore[operator]
        f"{_raised_clause(info)}{report.sizes.count} communicates; {share}; report {path}"
    )


def _content_clause(run_dir: Path, info: RunInfo, c: ContentOutcome) -> str:
    """The last line's outcome of a run that poured: the robot's count of the spheres in the
    container, and the simulation's beside it when the world left its final scene
    (services/report/content.py ``content_line``); else how many commands there were."""
    from services.report.content import content_line
    from services.report.world import world_content

    if not any("pour" in text for text in info.commands):
        return f"{len(info.commands)} command(s)"
    return content_line(c, world_content(run_dir, c.container))


def _raised_clause(info: RunInfo) -> str:
    """``2 handler errors in a_ta: see logs/a_ta.log; `` (what the agents raised during the run,
    services/runtime/raised.py, and a separator), or "" when none did."""
    from services.runtime.raised import raised_text

    text = raised_text(info.raised, info.crashed)
    return f"{text}; " if text else ""


def _coverage_summary(run_dir: Path) -> CoverageSummary | None:
    """The run's specification coverage for its report (services/spec_check/coverage_figure.py);
    None, with one line saying why, when it cannot be counted: the report is written all the same."""
    from services.spec_check.coverage_figure import report_summary

    try:
        return report_summary(run_dir)
    except Exception as exc:  # the report stands without it
        typer.echo(f"roco: specification coverage not counted: {exc}", err=True)
        return None


@report_app.command(short_help="Write RUN/report.md from a run folder.")
def report(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")], spec: SpecFile = None
) -> None:
    """Write RUN/report.md from the run's traffic record and run.json, with the requirement
    tree traced to the run (`roco spec trace RUN`), laid out for the run's system (--spec, else
    the specification the run used: docs/method.md). A folder that is not a run folder
    (neither run.json nor traffic.jsonl in it) is refused, exit 2, nothing written."""
    import os

    from services.report import write_report
    from services.spec_check.trace import report_rows

    if spec is not None:  # what every part of the report reads the run with (run_folder.spec_for_run)
        os.environ[Settings.env_name("spec")] = str(chosen_spec(spec))

    try:
        typer.echo(
            str(write_report(run_folder(run_dir), coverage=_coverage_summary(run_dir), tracer=report_rows))
        )
    except OSError as exc:
        raise fail(f"cannot write the report in {run_dir}: {exc.strerror or exc}") from None


def fleet_end(run_dir: Path, failure: str = "") -> str:
    """Record the commands a fleet (`roco up`, `roco hosts up`, compose) was given and their
    outcomes in its run.json, write its report (services/report/ending.py) and return the words
    that say so."""
    from services.report.ending import end
    from services.spec_check.coverage_figure import report_summary
    from services.spec_check.trace import report_rows

    return end(
        run_dir, ended=time.time(), failure=failure, tracer=report_rows, coverage=report_summary
    ).line()
