"""Rendering a :class:`Report` as Markdown, with the paper's figures (§5.7, Tables 7 and 8)
beside or below this run's, and the PNG figures (:mod:`services.report.figures`) linked in the
sections they belong to."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path

from services.recorder.flags import LiveFlag
from services.report import paper
from services.report.figures import FigureFile
from services.report.model import (
    AgentMatrix,
    CommandRow,
    Event,
    Header,
    PerceptionRow,
    PlanPhase,
    Report,
    RequirementRow,
)
from services.report.robot_clock import RobotClock
from services.runtime.human import NOTICES_PER_S
from velma.executor.timing import STALL_OFF_CPU, TimingStats
from velma.realtime import RealtimeSetup
from velma.world.timing import DT, LATE_AFTER_S, MAX_BEHIND_S, STALL_PERIODS, WorldTiming

HOW_MEASURED = (
    "**How measured.** Two clocks. *Wall* times are the arrival times of the communicates at "
    "the traffic recorder, in seconds since the run start (`run.json` `started`, else the "
    "first record); a communicate a restarted recorder recovered late from its publisher's "
    "cache counts at the time its publisher stamped on it. *Robot* times are the simulation's "
    "clock, read from ag_ex's answers on C5 (each carries the simulation time it ended at) and "
    "interpolated between them: the robot's own time, which the paper's real robot shares with "
    "the wall clock; run as fast as possible, the simulation runs faster than the wall clock, "
    "so the comparisons with the paper use robot time. Sizes are the payload on the wire: "
    "the msgpack-encoded communicate "
    "(`TrafficRecord.size`). The paper logged send times and sizes of its ROS 1 messages, "
    "so sizes compare in order of magnitude only."
)
HOW_MEASURED_SYSTEM = (
    "**How measured.** Times are the arrival times of the communicates at the traffic recorder, "
    "in seconds since the run start (`run.json` `started`, else the first record). Sizes are the "
    "payload on the wire: the msgpack-encoded communicate (`TrafficRecord.size`)."
)


SECTION = "## § "
"""How a section's title begins before :func:`render` numbers the sections present, in order."""
PERCEPTION_SECTION = "§perception"
"""Stands for the perception section's number in text written before the numbering."""


def render(report: Report, figures: Sequence[FigureFile] = ()) -> str:
    """The whole report as Markdown text, its sections numbered without gaps (a section with
    nothing to show is left out); each of ``figures`` (written by
    :func:`services.report.figures.write_figures`) is linked, with its caption, in its section:
    sizes over time, bandwidth and size histogram in 1, the matrix in 2, the timeline in 3."""
    figs = {f.name: f for f in figures}
    if not report.paper:
        return _numbered([p for p in _system_parts(report) if p]) + "\n"
    parts = [
        _header(report.header, report.perception, report.commands),
        _statistics(report, figs),
        _matrix_section(report.matrix, figs),
        _timeline(report.events, report.clock, figs),
        _requirements(report.requirements, report.clock, report.flags, report.header.started_wall),
        _planning(report.plans),
        _content(report),
        _control(report),
        _coordination(report),
        _notices(report),
        _faults(report),
        _coverage(report),
        _perception(report),
        _notes(report.notes),
    ]
    return _numbered([p for p in parts if p]) + "\n"


def _system_parts(report: Report) -> list[str]:
    """The sections of the report of a system other than the paper's Robot Companion: its own
    channels and agents, its conversations, requirements, notices, faults and coverage."""
    h = report.header
    rows = [
        ["System", report.system],
        ["Run started", _wall(h.started_wall)],
        ["Run ended", _wall(h.ended_wall)],
        ["Last communicate", f"{_s(h.last_record_t)} s after the start"],
        ["Traffic record", h.record or "—"],
        *([["Agents raised", h.raised]] if h.raised else []),
        *([["Access control", h.access_control]] if h.access_control else []),
        *([["Link between the hosts", h.link]] if h.link else []),
    ]
    title = f"# Experiment report: {Path(h.run_dir).name}"
    head = "\n\n".join([title, f"Run folder: `{h.run_dir}`", _table(["", ""], rows), HOW_MEASURED_SYSTEM])
    s = report.sizes
    sizes = [
        ["communicates", str(s.count)],
        ["total size", _bytes(s.total_bytes)],
        ["min size", _bytes(s.min_bytes)],
        ["mean size", _bytes(s.mean_bytes)],
        ["max size", _bytes(s.max_bytes)],
    ]
    per_channel = [
        [c.channel, "–".join(report.channel_ends.get(c.channel, ())) or "—", str(c.count), _bytes(c.bytes)]
        for c in report.channels
    ]
    statistics = "\n\n".join(
        [
            f"{SECTION}Communication statistics",
            _table(["quantity", "this run"], sizes),
            "### Per channel",
            _table(["channel", "agents", "communicates", "bytes"], per_channel),
        ]
    )
    m = report.matrix
    matrix = "\n\n".join(
        [
            f"{SECTION}Communicates sent and received per agent (paper Table 8 layout)",
            "Rows: receivers; columns: senders. A communicate with several receivers counts once "
            "per receiver.",
            _matrix_table(m.agents, m.agents, m.cells, m.received, m.sent, m.total),
        ]
    )
    events = [[_span(e.start, e.end), e.text, ", ".join(e.channels) or "—"] for e in report.events]
    timeline = "\n\n".join(
        [
            f"{SECTION}Conversations (paper Table 7 layout)",
            "Each conversation from its first communicate to its last, s since the run start (wall "
            "time, at the recorder), with the performatives it took in order.",
            _table(["wall [s]", "conversation", "channels used"], events)
            if events
            else "No conversations: the traffic record is empty.",
        ]
    )
    return [
        head,
        statistics,
        matrix,
        timeline,
        _requirements(report.requirements, report.clock, report.flags, h.started_wall),
        _notices(report),
        _faults(report),
        _coverage(report),
        _notes(report.notes),
    ]


def _numbered(parts: list[str]) -> str:
    """``parts`` joined, each ``SECTION`` title given the next number and each mention of the
    perception section its number."""
    number = 0
    perception = "—"
    out = []
    for part in parts:
        if part.startswith(SECTION):
            number += 1
            part = f"## {number}. {part[len(SECTION) :]}"
            if part.startswith(f"## {number}. Perception"):
                perception = str(number)
        out.append(part)
    return "\n\n".join(out).replace(PERCEPTION_SECTION, perception)


def _figure(figs: Mapping[str, FigureFile], *names: str) -> list[str]:
    """Markdown for the figures ``names`` that were drawn: the image (relative link) and a
    one-paragraph caption saying how it was measured."""
    out = []
    for name in names:
        f = figs.get(name)
        if f is not None:
            out += [f"![{f.title}]({f.path})", f"*{f.title}.* {f.caption}"]
    return out


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _s(x: float | None) -> str:
    return "—" if x is None else f"{x:.1f}"


def _span(start: float, end: float | None) -> str:
    if end is None or f"{end:.1f}" == f"{start:.1f}":
        return _s(start)
    return f"{_s(start)}–{_s(end)}"


def _bytes(n: float | None) -> str:
    if n is None:
        return "—"
    text = f"{n:.0f} B" if isinstance(n, int) else f"{n:.1f} B"
    return text if n < 1000 else f"{text} ({n / 1000:.1f} kB)"


def _pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f} %"


def _kbps(x: float | None) -> str:
    return "—" if x is None else f"{x:.1f}"


def _wall(t: float | None) -> str:
    if t is None:
        return "—"
    return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _perceived(rows: Sequence[PerceptionRow]) -> str:
    """The header's perception row: the head camera's Observations (their section), or none logged."""
    if rows:
        observations = len({r.sim_time for r in rows})
        seen = f"head camera: {observations} Observation(s)"
        return f"{seen}, beside the ground truth in section {PERCEPTION_SECTION}"
    return (
        "no head-camera Observation logged: the physics' ground truth answered the agents "
        "(ROCO_PERCEPTION=truth, or no off-screen GL library), or nothing was observed"
    )


def _header(h: Header, perception: Sequence[PerceptionRow] = (), commands: Sequence[CommandRow] = ()) -> str:
    outcome = {None: "unknown", True: "succeeded", False: "failed"}[h.succeeded]
    if h.detail:
        outcome += f" — {h.detail}"
    outcome += f" (source: {h.outcome_source})"
    rows = [
        ["Command", h.command or "—"],
        ["Outcome", outcome],
        ["Task duration" if len(commands) < 2 else "Task durations", _duration(h, commands)],
        ["Run started", _wall(h.started_wall)],
        ["Command sent", _wall(h.command_wall)],
        ["Run ended", _wall(h.ended_wall)],
        ["Last communicate", f"{_s(h.last_record_t)} s after the start"],
        ["Traffic record", h.record or "—"],
        ["Perception", _perceived(perception)],
    ]
    if h.raised:
        rows.append(["Agents raised", h.raised])
    if h.access_control:
        rows.append(["Access control", h.access_control])
    if h.link:
        rows.append(["Link between the hosts", h.link])
    if h.ledger:
        rows.append(["ag_ex's ledger", h.ledger])
    title = f"# Experiment report: {Path(h.run_dir).name}"
    return "\n\n".join([title, f"Run folder: `{h.run_dir}`", _table(["", ""], rows), HOW_MEASURED])


def _duration(h: Header, commands: Sequence[CommandRow]) -> str:
    """The header's task duration: robot time and wall clock from the command to the outcome,
    or each command's with several (:func:`_each_duration`)."""
    if len(commands) > 1:
        return _each_duration(h, commands)
    if h.task_duration_s is None:
        return "— (command or outcome not recorded)"
    return (
        f"{_robot_time(h.robot_duration_s)}; {_s(h.task_duration_s)} s wall (human command at "
        f"{_s(h.command_t)} s → outcome at {_s(h.finished_t)} s)"
    )


def _took(c: CommandRow) -> str:
    """A command's wall-clock duration, or that it has not ended."""
    return "not ended" if c.took_s is None else f"{_s(c.took_s)} s"


def _each_duration(h: Header, commands: Sequence[CommandRow]) -> str:
    """The header's durations of several commands: each from its request to its outcome (wall
    clock and robot time), then the span from the first request to the last outcome."""
    each = "; ".join(
        f"#{i} {_took(c)} wall, {_robot_time(c.robot_s)} (at {_s(c.requested_t)} s)"
        for i, c in enumerate(commands, 1)
    )
    span = f"{_s(h.task_duration_s)} s wall" if h.task_duration_s is not None else "—"
    first_to_last = f"first command → last outcome: {span}"
    return f"{len(commands)} commands, each from its request to its outcome: {each}; {first_to_last}"


def _statistics(report: Report, figs: Mapping[str, FigureFile]) -> str:
    s, h = report.sizes, report.header
    under = "—" if s.count == 0 else f"{_pct(s.share_under_500)} ({s.under_500} of {s.count})"
    paper_duration = (
        f"{paper.TASK_END_S:.0f} s from the log's start; "
        f"{paper.TASK_END_S - paper.COMMAND_T_S:.0f} s from the command at "
        f"{paper.COMMAND_T_S:.0f} s"
    )
    rows = [
        ["communicates", str(s.count), f"{paper.COMMUNICATES} (Table 8 totals {paper.TABLE8_TOTAL})"],
        ["total size", _bytes(s.total_bytes), "—"],
        ["min size", _bytes(s.min_bytes), f"{paper.MIN_SIZE_B} B"],
        ["mean size", _bytes(s.mean_bytes), f"{paper.MEAN_SIZE_B} B"],
        [
            "max size",
            _bytes(s.max_bytes),
            f"{paper.MAX_SIZE_B // 1000} kB (text also: {paper.MAX_SIZE_ALT_B // 1000} kB)",
        ],
        ["share under 0.5 kB (500 B)", under, f"{paper.SHARE_UNDER_500 * 100:.0f} %"],
        ["task duration (robot time)", _robot_time(h.robot_duration_s), paper_duration],
        ["task duration (wall clock)", f"{_s(h.task_duration_s)} s", "the same (a real robot)"],
    ]
    if len(report.commands) > 1:  # one task per command: each its own duration
        rows[-2:] = [
            [
                "task duration (robot time)",
                ", ".join(f"#{i} {_robot_time(c.robot_s)}" for i, c in enumerate(report.commands, 1)),
                paper_duration,
            ],
            [
                "task duration (wall clock)",
                ", ".join(f"#{i} {_took(c)}" for i, c in enumerate(report.commands, 1)),
                "the same (a real robot)",
            ],
        ]
    derived = paper.table8_channel_counts()
    ch_rows = []
    for c in report.channels:
        ends = paper.CHANNEL_ENDS.get(c.channel)
        ch_rows.append(
            [
                c.channel,
                "–".join(ends) if ends else "—",
                str(c.count),
                _bytes(c.bytes),
                str(derived.get(c.channel, 0)) if ends else "—",
            ]
        )
    ch_rows.append(["none", "a_km–ag_ex", "—", "—", str(derived.get("none", 0))])
    return "\n\n".join(
        [
            f"{SECTION}Communication statistics",
            _table(["quantity", "this run", "paper (§5.7)"], rows),
            "### Per channel",
            _table(
                [
                    "channel",
                    "agents",
                    "this run: communicates",
                    "this run: bytes",
                    "paper: communicates (derived from Table 8)",
                ],
                ch_rows,
            ),
            *_figure(figs, "sizes_over_time", "bandwidth", "size_histogram"),
        ]
    )


def _matrix_table(
    agents: Sequence[str],
    rows: Sequence[str],
    cells: dict[str, dict[str, int]],
    received: dict[str, int],
    sent: dict[str, int],
    total: int,
) -> str:
    body = []
    for r in rows:
        row = cells.get(r, {})
        body.append([r] + [str(row[s]) if row.get(s) else "" for s in agents] + [str(received.get(r, 0))])
    body.append(["send"] + [str(sent.get(s, 0)) for s in agents] + [str(total)])
    return _table(["receiver \\ sender", *agents, "Received"], body)


def _matrix_section(m: AgentMatrix, figs: Mapping[str, FigureFile]) -> str:
    ours = _matrix_table(m.agents, m.agents, m.cells, m.received, m.sent, m.total)
    theirs = _matrix_table(
        paper.AGENTS,
        list(paper.TABLE8),
        paper.TABLE8,
        paper.table8_received(),
        paper.table8_sent(),
        paper.TABLE8_TOTAL,
    )
    return "\n\n".join(
        [
            f"{SECTION}Communicates sent and received per agent (paper Table 8 layout)",
            "Rows: receivers; columns: senders. A communicate with several receivers counts "
            "once per receiver.",
            "**This run**",
            ours,
            "**Paper, Table 8** (no a_hi row; a_km ↔ ag_ex cells have no channel in the "
            "specification; totals 1865 against 1856 in the text)",
            theirs,
            *_figure(figs, "matrix"),
        ]
    )


def _robot_time(x: float | None) -> str:
    return "— (no answer of ag_ex in between)" if x is None else f"{x:.1f} s robot time"


def _robot_span(clock: RobotClock, start: float, end: float | None) -> str:
    """The robot times of a wall-clock span; — where the robot's clock is not known."""
    a = clock.at(start)
    if end is None:
        return _s(a)
    b = clock.at(end)
    if a is None and b is None:
        return "—"
    return _span(a, b) if a is not None and b is not None else f"{_s(a)}–{_s(b)}"


REQUIREMENTS_NOTE = (
    "Each requirement of the specification (paper Figure 5) with the decomposition steps and "
    "channels that serve it, its properties (what must have happened, in order and linked by "
    "conversation-id and in-reply-to; its `properties` in the specification) with their verdict "
    "in this run and when the first and the last matched event arrived, the tests that name it "
    "(`@pytest.mark.requirement`) and the verdict: *violated* when `roco spec verify` found a "
    "violation on a channel serving it, for a requirement about the task a command failed, or "
    "a property's situation happened and the rest did not follow; *shown* when every property "
    "held; else *not exercised*. A requirement with children is shown when all its leaves are. "
    "The same as `roco spec trace RUN` (docs/spec.md)."
)


def _requirement_row(r: RequirementRow, clock: RobotClock) -> list[str]:
    name = f"{r.id} {r.text}"
    served = "; ".join(x for x in (", ".join(f"step {n}" for n in r.steps), ", ".join(r.channels)) if x)
    when = "—" if r.first_t is None else _robot_span(clock, r.first_t, r.last_t)
    wall = "—" if r.first_t is None else _span(r.first_t, r.last_t)
    verdict = f"**{r.verdict}**" + (f" ({'; '.join(r.against)})" if r.against else "")
    return [name, served or "—", "; ".join(r.evidence) or "—", when, wall, str(r.tests), verdict]


FLAGS_NOTE = (
    "Flagged violated during the run by the live monitor (run in the traffic recorder; "
    "`flags.jsonl`), each with the communicate that violated the property, when it arrived "
    "(s since the run start) and what it came before:"
)


def _requirements(
    rows: Sequence[RequirementRow], clock: RobotClock, flags: Sequence[LiveFlag] = (), t0: float | None = None
) -> str:
    """The requirement tree traced to this run: a generalised paper Table 7 (Table 7 says
    which channels each event used; this says which channels and communicates show each
    requirement), and the properties the live monitor flagged violated during the run (times
    from ``t0``, the run's start, POSIX s). Empty when the requirements were not traced and
    nothing was flagged."""
    if not rows and not flags:
        return ""
    head = ["requirement", "served by", "communicates", "robot [s]", "wall [s]", "tests", "verdict"]
    parts = [f"{SECTION}Requirements traced to this run (paper Table 7 generalised)"]
    if rows:
        parts += [REQUIREMENTS_NOTE, _table(head, [_requirement_row(r, clock) for r in rows])]
    if flags:
        parts += [FLAGS_NOTE, "\n".join(f"- **violated** {f.line(t0)}" for f in flags)]
    return "\n\n".join(parts)


def _timeline(events: Sequence[Event], clock: RobotClock, figs: Mapping[str, FigureFile]) -> str:
    ours = [
        [_robot_span(clock, e.start, e.end), _span(e.start, e.end), e.text, ", ".join(e.channels) or "—"]
        for e in events
    ]
    theirs = [list(row) for row in paper.TABLE7]
    return "\n\n".join(
        [
            f"{SECTION}Event timeline (paper Table 7 layout)",
            "**This run**: robot time (the simulation's clock) and wall time (the recorder's), s "
            "since the run start; — where ag_ex had not yet answered or answered no more",
            _table(["robot [s]", "wall [s]", "event", "channels used"], ours)
            if ours
            else "No events: the traffic record is empty.",
            "**Paper, Table 7** (the real robot: robot time is wall time)",
            _table(["time [s]", "event", "channels used"], theirs),
            *_figure(figs, "timeline"),
        ]
    )


def _planning(plans: Sequence[PlanPhase]) -> str:
    head = [
        "plan",
        "requested [s wall]",
        "answered [s wall]",
        "C4 communicates",
        "C4 bytes",
        "query-refs",
        "a_km queries (plan)",
        "planning time (plan) [s wall]",
        "mean kbps",
        "peak kbps (1 s)",
        "result",
    ]
    rows = [
        [
            f"#{p.index}",
            _s(p.requested_t),
            _s(p.received_t),
            str(p.c4_count),
            _bytes(p.c4_bytes),
            str(p.c4_queries),
            "—" if p.km_queries is None else str(p.km_queries),
            _s(p.planning_time_s),
            _kbps(p.mean_kbps),
            _kbps(p.peak_kbps),
            p.outcome,
        ]
        for p in plans
    ]
    paper_rows = [
        [
            f"#{p.number}",
            f"{p.requested:.0f}",
            f"{p.received:.0f}",
            str(p.c4_communicates),
            f"{p.generated_until - p.requested:.0f}",
            f"{p.mean_kbps:.0f}",
            "—" if p.peak_kbps is None else f"{p.peak_kbps:.0f}",
        ]
        for p in paper.PLANS
    ]
    return "\n\n".join(
        [
            f"{SECTION}Planning phases",
            "C4 traffic counted from the plan request (C3) to a_pl's answer; mean bandwidth "
            "over that span, peak over 1 s bins (paper Figure 13).",
            _table(head, rows) if rows else "No plan request (C3) in the traffic.",
            "**Paper** (§5.7, Table 7, Figure 13)",
            _table(
                [
                    "plan",
                    "requested [s]",
                    "received [s]",
                    "C4 communicates",
                    "generation [s]",
                    "mean kbps",
                    "peak kbps",
                ],
                paper_rows,
            ),
        ]
    )


def _content(report: Report) -> str:
    c = report.content
    if not c.observed:
        text = f"Spheres in the {c.container}: not observed (no L_SD Observation reports them)."
    else:
        which = "second" if c.look == 2 else "first"
        split = (
            f"{c.seen} seen and {c.inferred} inferred behind its wall (not seen)"
            if c.inferred
            else ("all seen" if c.inferred == 0 else "not split into seen and inferred")
        )
        text = (
            f"{c.inside} of {c.total} spheres ({_pct(c.share)}) ended in the {c.container}: "
            f"{split}, at the {which} look, the last observation (ag_ex → a_ta, C5) at "
            f"{_s(c.t)} s wall ({_s(c.stamp)} s robot time)."
        )
    return "\n\n".join(
        [
            f"{SECTION}Content outcome",
            text,
            "Paper: “the content of the jar is poured into the bowl” at 763 s; no count given.",
        ]
    )


def _scheduling(setup: RealtimeSetup) -> str:
    """The sentence on the scheduling the loop was granted: policy, CPU, wake-up latency."""
    pin_text = f"pinned to CPU {setup.cpus[0]}" if setup.pinned and setup.cpus else "not pinned"
    policy = f"{setup.policy} priority {setup.priority}" if setup.policy == "SCHED_FIFO" else setup.policy
    why = f" ({'; '.join(setup.notes)})" if setup.notes else ""
    qos = (
        ""
        if setup.cpu_latency_us is None
        else f", CPU wake-up latency held at {setup.cpu_latency_us} µs (PM QoS)"
    )
    return f"Scheduling: {policy}, {pin_text}{qos}{why}."


def _control(report: Report) -> str:
    c = report.control
    title = f"{SECTION}Control loop (ag_ex, 1 kHz)"
    if c is None:
        return f"{title}\n\nNot recorded (see Notes)."
    head = ("", "p50", "p99", "max")
    rows = [
        (
            "compute time per cycle (µs)",
            f"{c.compute_p50_us:.0f}",
            f"{c.compute_p99_us:.0f}",
            f"{c.compute_max_us:.0f}",
        ),
        *(
            (f"… of it {p.name} (µs)", f"{p.p50_us:.0f}", f"{p.p99_us:.0f}", f"{p.max_us:.0f}")
            for p in c.parts
        ),
        (
            "lateness of the cycle start (µs)",
            f"{c.lateness_p50_us:.0f}",
            f"{c.lateness_p99_us:.0f}",
            f"{c.lateness_max_us:.0f}",
        ),
    ]
    granted = "The loop did not report its scheduling." if c.setup is None else _scheduling(c.setup)
    if c.control_law:
        granted += f" Impedance law: {c.control_law}."
    if c.plant:
        granted += f" MuJoCo side of the cycle: {c.plant}."
    text = (
        f"Pacing: {c.pacing}. {c.cycles} cycles ({c.sim_time:.1f} s of simulation); "
        f"{c.overruns} overruns ({c.overrun_share * 100:.3f} %), at most "
        f"{c.max_consecutive_overruns} in a row; the longest cycle took {c.worst_compute_us:.0f} µs "
        f"(cycle {c.worst_cycle}, simulation time {c.worst_cycle * 0.001:.3f} s). {_stalls(c)}{granted} "
        f"Percentiles over the last {c.window} cycles."
    )
    how = (
        "**How measured.** `time.perf_counter` in the loop process around each cycle (command "
        "hand-off, motion primitive, control law, physics step, state publication); lateness "
        "is the start's delay after the cycle's release time; an overrun is a cycle that "
        "ended after the next release time (velma/executor/timing.py). The parts of the compute "
        "time are measured in the same cycles: primitive (the motion primitive's step), control "
        "(impedance law, hands, head), physics (`mj_step`, contact scan), hand-offs (the rest); "
        "each part's percentiles are its own, so they do not add up to the cycle's."
    )
    return "\n\n".join([title, text, _table(head, rows), how, _world(c.world)])


def _world(w: WorldTiming | None) -> str:
    """The world process's own timing beside the loop's (velma/world/timing.py)."""
    if w is None:
        return "**The world's cycle.** No figures: the physics ran in the loop, or ag_ex read none."
    ages = " / ".join(str(n) for n in w.stale_by_age)
    rows = [
        ("cycles (of them paced on the wall clock)", f"{w.cycles} ({w.paced})", ""),
        (
            f"late cycles (started over {LATE_AFTER_S * 1e3:.0f} ms after due)",
            str(w.late),
            f"{w.late_max_us:.0f} µs",
        ),
        (f"schedule resets (over {MAX_BEHIND_S * 1e3:.0f} ms behind)", str(w.resets), ""),
        (
            f"stalls (over {STALL_PERIODS * DT * 1e3:.0f} ms between cycle starts, waits excluded)",
            str(w.stalls),
            f"{w.gap_max_us:.0f} µs",
        ),
        (
            f"stale commands (by age 1 … {len(w.stale_by_age)} cycles: {ages})",
            str(w.stale),
            f"age {w.stale_worst_age}" if w.stale else "",
        ),
        ("steps held (no command applied)", str(w.held), ""),
        ("… of them between two applied commands (the controller's came too late)", str(w.held_attached), ""),
        ("waits for the controller's command", str(w.waits), f"{w.wait_max_us:.0f} µs"),
    ]
    how = (
        f"**The world's cycle** (velma/world/, pacing: {w.pacing}), counted by the world process "
        "over its run (velma/world/timing.py) and read from the robot link by ag_ex. A paced cycle "
        "is due at a wall-clock time (real time, or while the safety layer holds the robot); a "
        "stale command answers an older state than the newest the step could have had (real time "
        "only: in lockstep the world waits for the newest); a held step applied no command (before "
        "the controller attached, after it ended, or its command too old)."
    )
    return "\n\n".join([_table(("world process", "count", "worst"), rows), how])


def _coordination(report: Report) -> str:
    title = f"{SECTION}Commands and coordination (C2, C1)"
    if not report.commands and not report.coordination:
        return f"{title}\n\nNo command reached a_co."
    rows = [
        (
            str(i),
            c.text,
            str(c.priority),
            _s(c.requested_t),
            _s(c.cancelled_t) if c.cancelled_t is not None else "",
            _s(c.ended_t) if c.ended_t is not None else "",
            _s(c.took_s) if c.took_s is not None else "",
            c.outcome or "no outcome",
            c.detail,
        )
        for i, c in enumerate(report.commands, 1)
    ]
    commands = _table(
        (
            "#",
            "command",
            "priority",
            "requested (s wall)",
            "stopped (s wall)",
            "ended (s wall)",
            "took (s wall)",
            "outcome",
            "detail",
        ),
        rows,
    )
    events = _table(
        ("t (s wall)", "who", "performative", "what"),
        [(_s(e.t), e.who, e.performative, e.text) for e in report.coordination],
    )
    how = (
        "**How read.** Commands are the C2 fipa-request conversations (a_hi → a_co); the second "
        "table lists the coordinate protocol on C1: a_co's plan requests and cancels, and a_ta's "
        "Terminating (first of each conversation), Preempted, Replan, Succeeded and Error "
        "informs. A preemption reads: cancel → Terminating → (safe stop) → Preempted, then the "
        "urgent command's plan, then the preempted command's new plan."
    )
    return "\n\n".join([title, commands, events, how])


def _notices(report: Report) -> str:
    """What agents told the person through a_hi, only when one did (services/report/notices.py)."""
    if not report.notices:
        return ""
    rows = [(_s(n.t), n.sender, n.severity or "—", " ".join(n.about) or "—", n.text) for n in report.notices]
    table = _table(("time (s wall)", "sender", "severity", "about", "text"), rows)
    how = (
        "**How read.** Every `inform` of a notice protocol (one inform that nothing answers, as "
        "`roco-notify`) or carrying an L_HC `Notice` in the traffic record: an agent telling the "
        "person something unprompted through a_hi. The text is what a_hi tells the person: a "
        "`Notice`'s text, or the term's own sentence (its `told()`), else its string form; the "
        f"sender is the communicate's. a_hi passes on at most {NOTICES_PER_S} a second per sender (the rest "
        "it counts as `notices_dropped`, which `roco status` shows): the record holds every one sent."
    )
    return f"{SECTION}Notices to the person\n\n{table}\n\n{how}"


def _faults(report: Report) -> str:
    """The faults section, only when faults were injected (``faults.jsonl``, docs/faults.md)."""
    if not report.faults:
        return ""
    rows = [
        (f.kind, f.by, f.where, str(f.count), _s(f.first_t), _s(f.last_t), f.detail[:120])
        for f in report.faults
    ]
    how = (
        "**How read.** `faults.jsonl`: one event per fault applied by an agent's transport "
        "(message faults on a channel, network faults of a service, settings changes) or by "
        "`roco fault` (`roco`: process faults), grouped by kind, injector and channel or service; "
        "times are when the fault was applied, in s since the run start. Dropped communicates "
        "are not in the traffic record; corrupted ones are, as sent (often `malformed`)."
    )
    table = _table(("kind", "by", "where", "count", "first (s wall)", "last (s wall)", "detail (last)"), rows)
    return f"{SECTION}Injected faults\n\n{table}\n\n{how}"


def _coverage(report: Report) -> str:
    """The specification-coverage section, when the report's writer counted it."""
    c = report.coverage
    if c is None:
        return ""
    share = f"{100 * c.exercised / c.items:.1f} %" if c.items else "–"
    rows = [(name, f"{done} of {n}") for name, done, n in c.kinds if n]
    parts = [
        f"{SECTION}Specification coverage",
        f"This run exercised **{c.exercised} of {c.items}** parts of the specification ({share}).",
        _table(("part", "exercised"), rows),
    ]
    if c.figure:
        parts.append(
            f"![Specification coverage]({c.figure})\n*Specification coverage.* The agent graph (each "
            "channel: its parts exercised) and each interaction protocol's state machine and agent's FSM, "
            "each edge coloured by how often the run took it (blue, log scale; red, dashed: never)."
        )
    if c.never:
        parts.append("Never taken (first of them): " + "; ".join(f"`{n}`" for n in c.never) + ".")
    parts.append(
        '**How counted.** `roco spec coverage RUN` (docs/spec.md, "Coverage"): the traffic record\'s '
        "conversations followed through their protocols' state machines, the agents' FSM records "
        "(`fsm/`) and the content terms of the specification. " + " ".join(c.notes)
    )
    return "\n\n".join(parts)


def _or_dash(value: int | None) -> str:
    return "–" if value is None else str(value)


def _perception_row(r: PerceptionRow) -> tuple[str, ...]:
    """One object of one Observation beside the ground truth (empty where not measured)."""
    return (
        f"{r.sim_time:.1f}",
        r.object,
        "yes" if r.seen else "**no**",
        "" if r.error_mm is None else f"{r.error_mm:.1f}",
        "" if r.sigma_mm is None else f"{r.sigma_mm:.1f}",
        "" if r.content_truth is None else f"{_or_dash(r.content)} / {r.content_truth}",
        "" if r.outside is None else f"{r.outside} / {_or_dash(r.outside_truth)}",
        _cell(r.reason or ""),
        "" if r.observe_ms is None else f"{r.observe_ms:.0f}",
    )


def _perception_summary(rows: Sequence[PerceptionRow]) -> str:
    """How many requested objects were seen, and the position errors' p50 / p95 / max."""
    errors = sorted(r.error_mm for r in rows if r.error_mm is not None)
    seen = sum(r.seen for r in rows)
    summary = f"{seen} of {len(rows)} requested objects seen"
    if errors:
        p = lambda q: errors[min(len(errors) - 1, int(q * (len(errors) - 1) + 0.5))]  # noqa: E731
        summary += f"; position error p50 {p(0.5):.1f} mm, p95 {p(0.95):.1f} mm, max {errors[-1]:.1f} mm"
    return summary


def _perception(report: Report) -> str:
    """The perception section, only for runs that perceived with the head camera: every object of every
    Observation beside the ground truth, and the errors' p50 / p95 / max."""
    rows = report.perception
    if not rows:
        return ""
    table = _table(
        (
            "t (s wall)",
            "object",
            "seen",
            "error (mm)",
            "σ (mm)",
            "content / truth",
            "outside / truth",
            "why not seen",
            "Observe (ms)",
        ),
        [_perception_row(r) for r in rows],
    )
    summary = _perception_summary(rows)
    how = (
        "**How read.** `ag_ex_perception.jsonl`: ag_ex's record of each head-camera Observation "
        "(velma/executor/perception_log.py), the estimate beside the ground truth of the same "
        "captured world state. The truth is the simulation's, for this report only: the agents "
        "never receive it. Content: the spheres the camera counted beside those inside; outside: "
        "those it saw resting outside every container (spilled in view) beside those in none."
    )
    return f"{SECTION}Perception (head camera)\n\n{summary}.\n\n{table}\n\n{how}"


def _stalls(c: TimingStats) -> str:
    """The sentence on stalls of the loop's section (empty when the loop did not measure its
    CPU time)."""
    if not c.off_cpu_max_us:
        return ""
    return (
        f"{c.long_cycles} cycles took over 1 ms; "
        f"{c.stalls} cycles stalled (off their CPU for more than {STALL_OFF_CPU * 1e6:.0f} µs: the machine "
        f"took it; at most {c.off_cpu_max_us:.0f} µs); the longest other cycle took "
        f"{c.compute_max_outside_stalls_us:.0f} µs. "
    )


def _notes(notes: Sequence[str]) -> str:
    body = "\n".join(f"- {n}" for n in notes) if notes else "None: every file was read completely."
    return f"## Notes\n\n{body}"
