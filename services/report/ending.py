"""The end of a fleet that was given its commands from outside (``roco up``, ``roco hosts up``:
``roco send`` from this host or another, ``--router``): what it was asked and how each command
ended, taken from what the fleet itself recorded, into ``run.json``; then its report.

A fleet of ``roco up`` does not see ``roco send`` run; its traffic recorder sees every
communicate, so the commands are those a_hi passed to a_co on C2 (an L_HC ``HumanCommand``
request, paper §5.2) and their outcomes a_co's answers in the same conversation (a
``CommandOutcome``, a failure or refuse; after the person's cancel, stopped): services/report/
coordination.py ``commands``. A sentence a_hi did not understand never reaches C2 and is no
command given to the fleet.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from services.report.build import Tracer, write_run_report
from services.report.coordination import commands
from services.report.load import RunData, load_run
from services.report.model import CoverageSummary
from services.runtime.run_folder import RunCommand, RunInfo, write_run_info

CoverageCount = Callable[[Path], CoverageSummary]
"""Counts a run folder's specification coverage for its report (services/spec_check/
coverage_figure.py ``report_summary``: this layer does not import the checks)."""
DONE = frozenset({"succeeded", "stopped"})
"""Outcomes that are no failure of the fleet: done, or stopped because the person asked."""


@dataclass(frozen=True)
class Ending:
    """What :func:`end` left in a fleet's run folder: ``run.json``'s ``info``, the report's
    ``path`` and how many ``communicates`` it counts; ``problem``: why the report (or
    ``run.json``) was not written, "" when it was."""

    info: RunInfo
    path: Path | None = None
    communicates: int = 0
    problem: str = ""
    uncounted: str = ""
    """Why the report has no coverage section, "" when it has one or none was asked."""
    paper: bool = True
    """The run is of the paper's Robot Companion, whose commands (C2) the line counts; another
    system's are not read from its traffic."""

    def line(self) -> str:
        """``after 312.4 s; 2 commands: 2 succeeded; 1234 communicates; report RUN/report.md``
        (or why there is no report); the time is the fleet's wall time from its start
        (``run.json`` ``started``)."""
        info = self.info
        took = f"after {info.ended - info.started:.1f} s; " if info.ended and info.started else ""
        took = took or "(its start unknown); "
        given = f"{took}{commands_summary(info.outcomes)}" if self.paper else took.removesuffix("; ")
        if self.path is None:
            return f"{given}; report not written: {self.problem}"
        left = f" (specification coverage not counted: {self.uncounted})" if self.uncounted else ""
        return f"{given}; {self.communicates} communicates; report {self.path}{left}"


def end(
    run_dir: Path,
    *,
    ended: float,
    failure: str = "",
    tracer: Tracer | None = None,
    coverage: CoverageCount | None = None,
) -> Ending:
    """Complete ``run_dir/run.json`` (:func:`conclude`) and write the report (services/report/
    build.py, its requirements traced by ``tracer``, its specification coverage counted by
    ``coverage``) of a fleet that ended at ``ended`` (POSIX s); ``failure``: why it ended
    before its time. Never raises for a folder that cannot be read or written:
    :attr:`Ending.problem` says why (and :attr:`Ending.uncounted` why the coverage is left out)."""
    try:
        run = load_run(run_dir)
        info = conclude(run, ended=ended, failure=failure)
    except OSError as exc:
        return Ending(RunInfo(), problem=_first_line(exc))
    run.info = info
    summary, uncounted = None, ""
    if coverage is not None:
        try:
            summary = coverage(run_dir)
        except Exception as exc:  # the report stands without it
            uncounted = _first_line(exc)
    try:
        path, report = write_run_report(run, coverage=summary, tracer=tracer)
    except Exception as exc:  # the fleet has ended whether or not its report can be made
        return Ending(info, problem=_first_line(exc))
    return Ending(info, path, report.sizes.count, uncounted=uncounted, paper=report.paper)


def _run_commands(run: RunData) -> list[RunCommand]:
    """The commands the fleet was given, each with its outcome (POSIX times)."""
    return [
        RunCommand(
            text=row.text,
            sent=run.t0 + row.requested_t,
            outcome=row.outcome,
            detail=row.detail,
            ended=None if row.ended_t is None else run.t0 + row.ended_t,
        )
        for row in commands(run.messages)
    ]


def _verdict(outcomes: Sequence[RunCommand], failure: str) -> tuple[bool | None, str]:
    """``succeeded`` and ``detail`` of run.json (see :func:`conclude`)."""
    given = "; ".join(
        f"#{n} {c.outcome or 'not ended when the fleet stopped'}: {c.detail or c.text}"
        for n, c in enumerate(outcomes, 1)
    )
    if failure:
        return False, f"{failure}; {given}" if given else failure
    succeeded = all(c.outcome in DONE for c in outcomes) if outcomes else None
    return succeeded, given or "no command was given"


def conclude(run: RunData, *, ended: float, failure: str = "") -> RunInfo:
    """Complete ``run.json`` of the run folder ``run`` (as read) for a fleet that ended at
    ``ended`` (POSIX s): the commands it was given (``commands``, ``command``,
    ``command_sent``), each with its outcome (``outcomes``), ``ended``, ``succeeded`` (every
    command done or stopped at the person's request; None when none was given) and
    ``detail`` (one ``#n outcome: sentence`` per command). ``failure``: why the fleet ended
    before its time (it did not start, it was interrupted): then ``succeeded`` is False and
    ``detail`` starts with it. Returns what it wrote. Raises OSError when it cannot write."""
    info = run.info if run.info is not None else RunInfo(started=run.t0)
    info.outcomes = _run_commands(run)
    info.commands = [c.text for c in info.outcomes]
    if info.outcomes:
        info.command = info.outcomes[0].text
        info.command_sent = info.outcomes[0].sent
    info.ended = ended
    info.succeeded, info.detail = _verdict(info.outcomes, failure)
    write_run_info(Path(run.run_dir), info)
    return info


def commands_summary(outcomes: Sequence[RunCommand]) -> str:
    """``no command given``, or ``3 commands: 2 succeeded, 1 not ended``."""
    if not outcomes:
        return "no command given"
    counts = Counter(c.outcome or "not ended" for c in outcomes)
    each = ", ".join(f"{n} {outcome}" for outcome, n in counts.items())
    return f"{len(outcomes)} command{'s' if len(outcomes) > 1 else ''}: {each}"


def _first_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror and exc.filename:
        return f"{exc.strerror}: {exc.filename}"
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
