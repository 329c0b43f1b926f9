"""``roco report``: a run's report with its requirements traced, and the report and the one-line
outcome a run of ``roco run``, ``scenario`` and ``chaos`` ends with
(services/spec_check/run_report.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from services.cli.common import INTERRUPTED, SpecFile, chosen_spec, fail, run_folder
from services.runtime.run_folder import RunInfo
from shared.settings import Settings

report_app = typer.Typer()


def warn(line: str) -> None:
    """A line on stderr that does not end the command."""
    typer.echo(line, err=True)


def finish_report(run_dir: Path, info: RunInfo, *, interrupted: bool = False) -> None:
    """Write the run's report and say in one line how the run went; when ``interrupted``
    (Ctrl-C, SIGTERM, SIGHUP: the runner stopped the fleet), say only that, and exit 130."""
    from services.spec_check.run_report import outcome_words, write_run_report

    try:
        path, report = write_run_report(run_dir, warn)
    except Exception as exc:  # the run's outcome stands even if its report cannot be made
        if interrupted:
            raise fail(f"interrupted; the fleet is stopped; run folder {run_dir}", INTERRUPTED) from None
        warn(f"roco: report not written: {exc}")
        return
    if interrupted:
        raise fail(f"interrupted; the fleet is stopped; report {path}", INTERRUPTED)
    typer.echo(f"roco: {outcome_words(run_dir, info, report, path)}")


@report_app.command(short_help="Write RUN/report.md from a run folder.")
def report(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")], spec: SpecFile = None
) -> None:
    """Write RUN/report.md from the run's traffic record and run.json, with the requirement
    tree traced to the run (`roco spec trace RUN`), laid out for the run's system (--spec, else
    the specification the run used: docs/method.md). A folder that is not a run folder
    (neither run.json nor traffic.jsonl in it) is refused, exit 2, nothing written."""
    import os

    from services.spec_check.run_report import write_traced_report

    if spec is not None:  # what every part of the report reads the run with (run_folder.spec_for_run)
        os.environ[Settings.env_name("spec")] = str(chosen_spec(spec))

    try:
        typer.echo(str(write_traced_report(run_folder(run_dir), warn)))
    except OSError as exc:
        raise fail(f"cannot write the report in {run_dir}: {exc.strerror or exc}") from None
