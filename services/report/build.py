"""Assembling the report of a run folder and writing ``report.md``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import msgspec

from services.recorder.flags import LiveFlag, read_flags
from services.recorder.record import (
    FAULTS_JSONL,
    LINK_BYTES_JSONL,
    read_fault_events,
    read_link_bytes,
    read_link_events,
)
from services.report import paper
from services.report.content import sphere_share
from services.report.coordination import commands, coordination
from services.report.figures import NOT_DRAWN, FigureFile, figures_wanted, write_figures
from services.report.ledger import judge_ledger
from services.report.load import Message, RunData, load_run
from services.report.markdown import render
from services.report.model import (
    CommandRow,
    ContentOutcome,
    CoverageSummary,
    FaultRow,
    Header,
    PerceptionRow,
    Report,
    RequirementRow,
)
from services.report.notices import notice_rows
from services.report.planning import plan_phases
from services.report.robot_clock import RobotClock, robot_clock
from services.report.stats import agent_matrix, channel_stats, size_stats
from services.report.timeline import (
    command_text,
    conversation_events,
    find_command,
    find_outcome,
    link_events,
    timeline,
)
from services.runtime.refusals import REFUSALS_JSONL, read_refusals
from services.runtime.run_folder import spec_for_run
from services.spec.model import SpecError, SystemSpec, load
from services.spec.notices import notice_protocols
from shared.fipa_codec.languages.l_hc import CommandOutcome
from velma.executor.capture import PERCEPTION_LOG as PERCEPTION_JSONL
from velma.executor.timing import TimingStats

TIMING_JSON = "ag_ex_timing.json"  # written by services/agents/executor/agent.py

REPORT_MD = "report.md"

Tracer = Callable[[RunData], list[RequirementRow]]
"""What traces the specification's requirements to a run (services/spec_check/trace.py
``report_rows``, which the tools pass in: it checks the run's conformance, a tool above this
package). Raises ValueError, one line, when it cannot."""


def build_report(run_dir: Path, container: str = "bowl") -> Report:
    """The report of ``run_dir`` as data. Raises FileNotFoundError when the folder does not
    exist; missing or corrupt files inside it become ``Report.notes``."""
    return _assemble(load_run(Path(run_dir)), container)


def _system(run_dir: Path, notes: list[str]) -> SystemSpec | None:
    """The specification the run is read with (services/runtime/run_folder.py
    ``spec_for_run``); None, with a note, when it does not load (the report is then the
    paper's Robot Companion's)."""
    try:
        return load(spec_for_run(run_dir))
    except SpecError as exc:
        notes.append(f"specification not read ({exc}): the report is laid out for the Robot Companion")
        return None


def _assemble(run: RunData, container: str = "bowl", tracer: Tracer | None = None) -> Report:
    """The report of a run folder already read; its requirements traced by ``tracer`` (None:
    not traced). A system other than the paper's Robot Companion gets its own channels, agents
    and conversations, and no kitchen section (:func:`_as_system`)."""
    notes = list(run.notes)
    system = _system(Path(run.run_dir), notes)
    if system is not None and system.system != paper.SYSTEM:
        return _as_system(run, system, tracer, notes)
    return _as_robot_companion(run, container, tracer, notes, system)


def _as_robot_companion(
    run: RunData, container: str, tracer: Tracer | None, notes: list[str], system: SystemSpec | None
) -> Report:
    """The report of a run of the paper's Robot Companion (:func:`_assemble`), compared with
    the paper, with the kitchen's sections."""
    run_dir = run.run_dir
    wire = run.messages
    # a copy (the same bytes again on the same key: Message.copy_of) crossed the wire, so the
    # channel figures count it; what happened is told once, from the originals
    messages = [m for m in wire if m.copy_of is None]
    command = find_command(messages)
    outcome = find_outcome(messages)
    plans = plan_phases(messages)
    if len(wire) > len(messages):
        notes.append(
            f"{len(wire) - len(messages)} communicate(s) recorded again byte for byte (retransmitted, "
            "or answers sent again for a copy): counted in the channel figures, told once elsewhere"
        )
    if messages and command is None:
        notes.append("no human command (C2 request) in the traffic")
    if messages and outcome is None:
        notes.append("no final outcome (C2 CommandOutcome or failure) in the traffic")
    control = _control_timing(Path(run_dir), notes)
    header = _header(run, command, outcome)
    clock = robot_clock(messages)
    header.robot_duration_s = clock.between(header.command_t, header.finished_t)
    header.record = run.integrity.summary() if run.integrity.records else ""
    header.access_control = _access_control(run)
    header.link = _link(Path(run_dir))
    header.ledger = _ledger(Path(run_dir), messages, notes)
    return Report(
        header=header,
        sizes=size_stats(wire),
        channels=channel_stats(wire),
        matrix=agent_matrix(wire),
        events=sorted(
            timeline(messages, plans, command, outcome)
            + link_events(read_link_events(Path(run_dir)), run.t0),
            key=lambda e: e.start,
        ),
        plans=plans,
        content=sphere_share(messages, container),
        notes=notes,
        control=control,
        commands=_timed(commands(messages), clock),
        coordination=coordination(messages),
        faults=_faults(run, notes),
        clock=clock,
        perception=_perception(Path(run_dir), notes),
        requirements=_requirements(run, tracer, notes),
        flags=_flags(Path(run_dir), notes),
        notices=notice_rows(messages, notice_protocols(system) if system is not None else frozenset()),
    )


def _as_system(run: RunData, system: SystemSpec, tracer: Tracer | None, notes: list[str]) -> Report:
    """The report of a run of a system other than the paper's: its header, sizes, its own
    channels and agents (Table 8 layout), its conversations as the timeline (Table 7 layout),
    its requirements, notices, faults and live flags; no paper figures, no kitchen section."""
    wire = run.messages
    messages = [m for m in wire if m.copy_of is None]
    header = _header(run, None, None)
    header.record = run.integrity.summary() if run.integrity.records else ""
    header.access_control = _access_control(run)
    header.link = _link(Path(run.run_dir))
    return Report(
        header=header,
        sizes=size_stats(wire),
        channels=channel_stats(wire, [c.name for c in system.channels]),
        matrix=agent_matrix(wire, system.agent_names),
        events=conversation_events(messages),
        plans=[],
        content=ContentOutcome(container="", observed=False),
        notes=notes,
        faults=_faults(run, notes),
        requirements=_requirements(run, tracer, notes),
        flags=_flags(Path(run.run_dir), notes),
        notices=notice_rows(messages, notice_protocols(system)),
        system=system.system,
        paper=False,
        channel_ends={c.name: c.ends for c in system.channels},
    )


def _timed(rows: list[CommandRow], clock: RobotClock) -> list[CommandRow]:
    """``rows`` with each command's duration in robot time (``CommandRow.robot_s``)."""
    for row in rows:
        row.robot_s = clock.between(row.requested_t, row.ended_t)
    return rows


def _ledger(run_dir: Path, messages: list[Message], notes: list[str]) -> str:
    """ag_ex's ledger held against the record, in one line (services/report/ledger.py); ""
    when the run has no ledger and no done answer of ag_ex; unreadable: a note."""
    try:
        v = judge_ledger(run_dir, messages)
    except OSError as exc:
        notes.append(f"ag_ex's ledger unreadable: {exc}")
        return ""
    return v.summary() if v.found or not v.ok else ""


def _flags(run_dir: Path, notes: list[str]) -> list[LiveFlag]:
    """The live monitor's flags of the run (services/recorder/flags.py); unreadable: a note."""
    try:
        return read_flags(run_dir)
    except OSError as exc:
        notes.append(f"live requirement flags unreadable: {exc}")
        return []


def _requirements(run: RunData, tracer: Tracer | None, notes: list[str]) -> list[RequirementRow]:
    """The requirement rows ``tracer`` gives (none without one); why it could not, as a note."""
    if tracer is None:
        return []
    try:
        return tracer(run)
    except ValueError as exc:
        notes.append(f"requirements not traced: {exc}")
        return []


def _link(run_dir: Path) -> str:
    """One line on what the link between two hosts carried: each way and its mean and busiest
    second as the relay counted it (``link_bytes.jsonl``: Zenoh and TLS, not TCP/IP), and the
    link device's totals (``link.jsonl`` ``counters``: everything on the wire); "" when the run
    has neither."""
    seconds = read_link_bytes(run_dir)
    parts = []
    if seconds:
        up, down = sum(s.up for s in seconds), sum(s.down for s in seconds)
        span = seconds[-1].t - seconds[0].t + 1
        peak = max(s.up + s.down for s in seconds)
        parts.append(
            f"robot → brain {up / 1e3:.1f} kB, brain → robot {down / 1e3:.1f} kB over {span:.0f} s: mean "
            f"{(up + down) * 8 / 1e3 / span:.1f} kbit/s, busiest second {peak * 8 / 1e3:.1f} kbit/s "
            f"(the relay's count, `{LINK_BYTES_JSONL}`: Zenoh and TLS, not TCP/IP)"
        )
    counters = [e for e in read_link_events(run_dir) if e.get("event") == "counters"]
    if counters:
        c = counters[-1]
        parts.append(
            f"on the link device: robot → brain {_kb(c.get('tx_bytes'))} in {c.get('tx_packets')} packets, "
            f"brain → robot {_kb(c.get('rx_bytes'))} in {c.get('rx_packets')} "
            "(TCP/IP and retransmissions included)"
        )
    return "; ".join(parts)


def _kb(n: object) -> str:
    return f"{n / 1e3:.1f} kB" if isinstance(n, int) else "?"


def _access_control(run: RunData) -> str:
    """One line: the refusals of the run's router by identity (``refusals.jsonl``,
    services/runtime/refusals.py) and the recorded spoofs its access control let through (a
    communicate on its sender's own key claiming another sender); "" without a refusals file."""
    run_dir = Path(run.run_dir)
    if not (run_dir / REFUSALS_JSONL).exists():
        return ""
    refused = [r for r in read_refusals(run_dir) if r.flow == "ingress"]
    by: dict[str, int] = {}
    for r in refused:
        by[r.identity] = by.get(r.identity, 0) + 1
    who = f" ({', '.join(f'{i} {n}' for i, n in sorted(by.items(), key=lambda kv: -kv[1]))})" if by else ""
    spoofs = sum(1 for m in run.messages if m.rec.key_sender is not None and m.rec.key_sender != m.sender)
    return (
        f"on; {len(refused)} message(s) refused{who} (`{REFUSALS_JSONL}`); {spoofs} recorded "
        "communicate(s) claim another sender than their key's"
    )


def _faults(run: RunData, notes: list[str]) -> list[FaultRow]:
    """The injected faults of ``faults.jsonl`` grouped by kind, injector and place; the same
    settings taken by several agents make one row naming them all."""
    events, bad = read_fault_events(Path(run.run_dir))
    if bad:
        notes.append(f"{FAULTS_JSONL}: {bad} unreadable line(s) skipped")
    rows: dict[tuple[str, str, str], FaultRow] = {}
    for ev in sorted(events, key=lambda e: e.t):
        t = ev.t - run.t0
        if ev.kind == "settings":
            key, where = (ev.kind, "", ev.detail), "—"
        else:
            where = ev.channel or ev.target or ev.agent
            key = (ev.kind, ev.agent, where)
        row = rows.get(key)
        if row is None:
            rows[key] = FaultRow(
                kind=ev.kind, by=ev.agent, where=where, count=1, first_t=t, last_t=t, detail=ev.detail
            )
            continue
        row.count += 1
        row.last_t = t
        row.detail = ev.detail
        if ev.agent not in row.by.split(", "):
            row.by = ", ".join(sorted([*row.by.split(", "), ev.agent]))
    return sorted(rows.values(), key=lambda r: (r.first_t, r.kind, r.by))


def _control_timing(run_dir: Path, notes: list[str]) -> TimingStats | None:
    path = run_dir / TIMING_JSON
    if not path.exists():
        notes.append(f"no {TIMING_JSON}: ag_ex did not write its control-loop timing")
        return None
    try:
        return msgspec.json.decode(path.read_bytes(), type=TimingStats)
    except (msgspec.DecodeError, OSError) as exc:
        notes.append(f"{TIMING_JSON} unreadable: {exc}")
        return None


def _perception(run_dir: Path, notes: list[str]) -> list[PerceptionRow]:
    """The rows of ``ag_ex_perception.jsonl`` (none when absent: a ground-truth run); a
    line that cannot be read becomes a note and is skipped."""
    path = run_dir / PERCEPTION_JSONL
    if not path.exists():
        return []
    rows: list[PerceptionRow] = []
    decoder = msgspec.json.Decoder(PerceptionRow)
    bad = 0
    for line in path.read_bytes().splitlines():
        if not line.strip():
            continue
        try:
            rows.append(decoder.decode(line))
        except msgspec.DecodeError:
            bad += 1
    if bad:
        notes.append(f"{PERCEPTION_JSONL}: {bad} unreadable line(s) skipped")
    return rows


def write_report(
    run_dir: Path, *, coverage: CoverageSummary | None = None, tracer: Tracer | None = None
) -> Path:
    """Build the report of ``run_dir``, draw its figures into ``run_dir/figures/`` (PNG, see
    :mod:`services.report.figures`) and write it as Markdown, figures linked, to
    ``run_dir/report.md``; returns that path. ``coverage``: the run's specification coverage,
    counted by the caller (``roco spec coverage``; None: no such section); ``tracer`` traces the
    requirements to the run (its section; None: left out). A figure that cannot be drawn
    becomes a note of the report. Raises FileNotFoundError when the folder does not exist."""
    return write_run_report(load_run(Path(run_dir)), coverage=coverage, tracer=tracer)[0]


def write_run_report(
    run: RunData, *, coverage: CoverageSummary | None = None, tracer: Tracer | None = None
) -> tuple[Path, Report]:
    """:func:`write_report` of a run folder already read: writes ``report.md`` and its figures
    into ``run.run_dir``; returns the path and the report. Raises OSError when they cannot be
    written."""
    run_dir = Path(run.run_dir)
    report = _assemble(run, tracer=tracer)
    report.coverage = coverage
    figures: list[FigureFile]
    if not report.paper:
        figures = []
        report.notes.append(
            f"figures not drawn: they compare a run with the paper's Robot Companion, not {report.system}"
        )
    elif figures_wanted():
        figures, notes = write_figures(run, report, run_dir)
        report.notes.extend(notes)
    else:
        figures = []
        report.notes.append(NOT_DRAWN)
    path = run_dir / REPORT_MD
    path.write_text(render(report, figures), encoding="utf-8")
    return path, report


def _outcome_of(h: Header, run: RunData, outcome: Message | None) -> None:
    """The task's outcome: a_co's C2 answer, else what run.json says."""
    info = run.info
    if outcome is not None:
        if isinstance(outcome.content, CommandOutcome):
            h.succeeded = outcome.content.succeeded
            h.detail = outcome.content.detail
            h.outcome_source = "C2 CommandOutcome"
        else:
            h.succeeded = False
            h.outcome_source = f"C2 {outcome.performative}"
        h.finished_t = outcome.t
    elif info is not None and info.succeeded is not None:
        h.succeeded = info.succeeded
        h.detail = info.detail
        h.outcome_source = "run.json"
        if info.ended is not None:
            h.finished_t = info.ended - run.t0


def _command_time(run: RunData, command: Message | None) -> float | None:
    """When the command was given (s since the run began): its C2 request, else run.json's."""
    if command is not None:
        return command.t
    if run.info is not None and run.info.command_sent is not None:
        return run.info.command_sent - run.t0
    return None


def _header(run: RunData, command: Message | None, outcome: Message | None) -> Header:
    info = run.info
    h = Header(run_dir=str(run.run_dir))
    h.command = command_text(command) or (info.command if info else "")
    _outcome_of(h, run, outcome)
    if not h.detail and info is not None:
        h.detail = info.detail
    h.command_t = _command_time(run, command)
    if h.command_t is not None and h.finished_t is not None:
        h.task_duration_s = h.finished_t - h.command_t
    if info is not None:
        h.started_wall = info.started or None
        h.command_wall = info.command_sent
        h.ended_wall = info.ended
    if run.messages:
        h.last_record_t = run.messages[-1].t
    h.raised = _raised(run)
    return h


def _raised(run: RunData) -> str:
    """What the agents raised during the run, in one line (services/runtime/raised.py): the
    error counters and restarts run.json keeps, else the counters of ``counters.json``; "" when
    neither is there."""
    from services.runtime.counters import read_counters
    from services.runtime.raised import raised_by_agent, raised_text

    info = run.info
    by_agent = info.raised if info is not None else {}
    crashed = info.crashed if info is not None else {}
    if not by_agent:
        try:
            by_agent = raised_by_agent({a: r.counters for a, r in read_counters(Path(run.run_dir)).items()})
        except (OSError, ValueError):  # none, or corrupt
            if not crashed:
                return ""
    return raised_text(by_agent, crashed) or NOTHING_RAISED


NOTHING_RAISED = "nothing: every agent's handler_errors and behaviour_errors were 0 when the commands ended"
"""The report's line of what the agents raised when none did."""
