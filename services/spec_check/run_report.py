"""A run's report with its requirements traced (services/spec_check/trace.py) and its
specification coverage: written for ``roco report``, at the end of a run, and at a fleet's end
(services/report/ending.py), with the words of the run's outcome line."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from services.report.model import ContentOutcome, CoverageSummary, Report
    from services.runtime.run_folder import RunInfo


def coverage_summary(run_dir: Path, warn: Callable[[str], None]) -> CoverageSummary | None:
    """The run's specification coverage for its report (services/spec_check/coverage_figure.py);
    None, with one line to ``warn`` saying why, when it cannot be counted: the report is written
    all the same."""
    from services.spec_check.coverage_figure import report_summary

    try:
        return report_summary(run_dir)
    except Exception as exc:  # the report stands without it
        warn(f"roco: specification coverage not counted: {exc}")
        return None


def write_traced_report(run_dir: Path, warn: Callable[[str], None]) -> Path:
    """Write ``run_dir``/report.md with the requirement tree traced to the run and its coverage
    (:func:`coverage_summary`, its ``warn``); its path. Raises OSError when it cannot be written."""
    from services.report import write_report
    from services.spec_check.trace import report_rows

    return write_report(run_dir, coverage=coverage_summary(run_dir, warn), tracer=report_rows)


def write_run_report(run_dir: Path, warn: Callable[[str], None]) -> tuple[Path, Report]:
    """The report a run ends with (:func:`write_traced_report`), and its figures as data."""
    from services.report import build_report

    path = write_traced_report(run_dir, warn)
    return path, build_report(run_dir)


def outcome_words(run_dir: Path, info: RunInfo, report: Report, path: Path) -> str:
    """``succeeded in 41.2 s wall; 312 communicates; 18 of 18 spheres …; report PATH``: how the
    run of ``run_dir`` went, once its report ``report`` is written at ``path``."""
    share = content_clause(run_dir, info, report.content)
    took = info.ended - info.started  # type: ignore[operator]
    return (
        f"{'succeeded' if info.succeeded else 'failed'} in {took:.1f} s wall; "
        f"{raised_clause(info)}{report.sizes.count} communicates; {share}; report {path}"
    )


def content_clause(run_dir: Path, info: RunInfo, c: ContentOutcome) -> str:
    """The last line's outcome of a run that poured: the robot's count of the spheres in the
    container, and the simulation's beside it when the world left its final scene
    (services/report/content.py ``content_line``); else how many commands there were."""
    from services.report.content import content_line
    from services.report.world import world_content

    if not any("pour" in text for text in info.commands):
        return f"{len(info.commands)} command(s)"
    return content_line(c, world_content(run_dir, c.container))


def raised_clause(info: RunInfo) -> str:
    """``2 handler errors in a_ta: see logs/a_ta.log; `` (what the agents raised during the run,
    services/runtime/raised.py, and a separator), or "" when none did."""
    from services.runtime.raised import raised_text

    text = raised_text(info.raised, info.crashed)
    return f"{text}; " if text else ""


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
