"""The report as data: what :func:`services.report.build_report` returns.

Conventions: times named ``*_t``/``start``/``end`` are seconds relative to the run start
(``run.json`` ``started``, else the first record); ``*_wall`` are POSIX seconds; sizes are
payload bytes on the wire (the msgpack-encoded communicate); bandwidths kbit/s (1000 bit/s).
"""

from __future__ import annotations

import msgspec

from services.recorder.flags import LiveFlag
from services.report.robot_clock import RobotClock
from velma.executor.timing import TimingStats


class Header(msgspec.Struct, kw_only=True):
    """What was asked, how it ended, and when.

    command: the human command's text (L_HC ``HumanCommand.text``, else ``run.json``).
    succeeded, detail: the outcome; ``outcome_source`` says where it was read
    (``"C2 CommandOutcome"``, ``"C2 failure"``, ``"run.json"`` or ``"none"``).
    command_t, finished_t: arrival of the command (C2 request a_hi → a_co) and of the final
    outcome (C2 inform/failure a_co → a_hi); task_duration_s is their difference (paper:
    778 s counted from the log's start, command at 83 s). With several commands these are the
    first command and the last outcome; each command's own duration is its ``CommandRow``'s.
    started_wall, command_wall, ended_wall: POSIX times from ``run.json`` (None if absent).
    """

    run_dir: str
    command: str = ""
    succeeded: bool | None = None
    detail: str = ""
    outcome_source: str = "none"
    command_t: float | None = None
    finished_t: float | None = None
    task_duration_s: float | None = None
    robot_duration_s: float | None = None
    """The task's duration in robot time (the simulation's clock): from ag_ex's first answer
    after the command to its last before the outcome (services/report/robot_clock.py)."""
    started_wall: float | None = None
    command_wall: float | None = None
    ended_wall: float | None = None
    last_record_t: float | None = None
    record: str = ""
    """The traffic record's integrity in one line (services/recorder/integrity.py), checked
    before anything else in this report read it."""
    access_control: str = ""
    """What the router's access control refused (``refusals.jsonl``) and how many recorded
    communicates claim another sender than their key names, in one line; "" when the run has
    no refusals file (access control off)."""
    raised: str = ""
    """What the agents raised during the run (their handler and behaviour errors, and the
    agents that exited by themselves and were started again), in one line; "" when the run
    folder keeps no counters (services/report/build.py)."""
    link: str = ""
    """What the link between two hosts carried (``roco hosts``: the relay's count,
    ``link_bytes.jsonl``, and the link device's counters), in one line; "" for one host."""
    ledger: str = ""
    """ag_ex's ledger of executed commands held against the record (services/report/ledger.py):
    commands started, ag_ex processes, and whether one ran twice or was answered done without
    running, in one line; "" when the run has no ledger and ag_ex answered nothing done."""


class SizeStats(msgspec.Struct, kw_only=True):
    """Sizes of all recorded communicates (paper §5.7: 1856 communicates, min 231 B,
    mean 654 B, max 98 kB, 86 % below 0.5 kB). min/mean/max are None when count is 0."""

    count: int
    total_bytes: int
    min_bytes: int | None
    mean_bytes: float | None
    max_bytes: int | None
    under_500: int
    share_under_500: float | None


class ChannelStats(msgspec.Struct, kw_only=True):
    """Communicates and bytes on one channel (C1..C6 or whatever the record names)."""

    channel: str
    count: int
    bytes: int


class AgentMatrix(msgspec.Struct, kw_only=True):
    """Paper Table 8 layout: ``cells[receiver][sender]`` = number of communicates (a
    communicate with several receivers counts once per receiver). ``received`` row sums,
    ``sent`` column sums, ``total`` their common sum; ``agents`` the row/column order."""

    agents: list[str]
    cells: dict[str, dict[str, int]]
    received: dict[str, int]
    sent: dict[str, int]
    total: int


class Event(msgspec.Struct, kw_only=True):
    """One row of the timeline (paper Table 7 layout): ``start`` and ``end`` (None for an
    instant) in s since run start, ``text``, the ``channels`` used, and a ``kind`` for
    filtering (``initial_knowledge``, ``command``, ``plan_request``, ``planning``,
    ``plan_received``, ``plan_failed``, ``execution``, ``cancel``, ``grasp``, ``release``,
    ``tilt``, ``observation``, ``action_failed``, ``self_contact``, ``environment``,
    ``finished``)."""

    start: float
    text: str
    channels: list[str]
    kind: str
    end: float | None = None


class PlanPhase(msgspec.Struct, kw_only=True):
    """One planning process (paper: #1 1598 C4 communicates 97–152 s, #2 57 in 681–682 s).

    index: ``GroundTaskNetwork.plan_index`` (else the request's ordinal); requested_t: C3
    request; received_t: a_pl's answer (None: no answer); c4_count/c4_bytes/c4_queries: C4
    communicates, their bytes and a_pl's ``query-ref``s between request and answer;
    c4_last_t: the last of them; mean_kbps: c4_bytes over [requested_t, received_t], at
    least one peak bin (1 s) long;
    peak_kbps: the busiest 1 s bin from requested_t (paper Figure 13). From the plan itself
    (L_HFSM ``HierarchicalPlan``): plan_id, km_queries, planning_time_s, complete.
    outcome: ``complete``, ``partial``, ``failed: <reason>`` or ``no answer``.
    """

    index: int
    requested_t: float
    received_t: float | None
    c4_count: int
    c4_bytes: int
    c4_queries: int
    c4_last_t: float | None
    mean_kbps: float | None
    peak_kbps: float | None
    outcome: str
    plan_id: str | None = None
    km_queries: int | None = None
    planning_time_s: float | None = None
    complete: bool | None = None


class ContentOutcome(msgspec.Struct, kw_only=True):
    """Spheres of the jar that ended in ``container``, from the last L_SD ``Observation``
    (ag_ex → a_ta, C5) reporting ``particles_inside`` for it. ``observed`` False when none;
    ``inside`` = ``seen`` + ``inferred``: the spheres the camera saw and those it inferred
    behind the container's wall (``inferred`` None: the observation does not split them);
    ``share`` = inside / total (None when total is 0); ``t`` arrival (s since run start);
    ``stamp`` simulation time of the observation (s); ``look`` 1 or 2: the first look at the
    container or the second, after a_ta turned the head to it (services/report/content.py)."""

    container: str
    observed: bool
    inside: int | None = None
    total: int | None = None
    share: float | None = None
    t: float | None = None
    stamp: float | None = None
    seen: int | None = None
    inferred: int | None = None
    look: int | None = None


class CommandRow(msgspec.Struct, kw_only=True):
    """One human command (C2 conversation): its ``text`` and ``priority``; when it was
    requested, cancelled by the person (None: never) and ended (s since run start);
    ``outcome`` succeeded / failed / stopped (None: no outcome recorded) with a_co's
    ``detail``."""

    conversation: str
    text: str
    priority: int = 0
    requested_t: float
    cancelled_t: float | None = None
    ended_t: float | None = None
    outcome: str | None = None
    detail: str = ""
    robot_s: float | None = None
    """The command's duration in robot time, from its request to its outcome
    (services/report/robot_clock.py ``between``); None when ag_ex answered nothing in between."""

    @property
    def took_s(self) -> float | None:
        """Wall-clock seconds from the request to the outcome; None when it has not ended."""
        return None if self.ended_t is None else self.ended_t - self.requested_t


class CoordinationEvent(msgspec.Struct, kw_only=True):
    """One C1 exchange of the coordinate protocol (paper Figure 8) that changes what the
    robot does: at ``t`` (s since run start), ``who`` (sender → receiver), the
    ``performative`` and what it says; ``conversation`` is the C1 conversation-id."""

    t: float
    who: str
    performative: str
    text: str
    conversation: str | None = None


class FaultRow(msgspec.Struct, kw_only=True):
    """Injected faults of one ``kind`` applied by ``by`` (an agent, or ``roco`` for process
    faults) on ``where`` (a channel, or the service hit): how many, the first and the last
    (s since run start), and the last event's ``detail``. From ``faults.jsonl``."""

    kind: str
    by: str
    where: str
    count: int
    first_t: float
    last_t: float
    detail: str = ""


class PerceptionRow(msgspec.Struct, kw_only=True):
    """One object of one camera Observation beside the truth of the same captured state
    (``ag_ex_perception.jsonl``, velma/executor/perception_log.py): simulation time (s),
    whether it was seen, the position error and the reported 1-σ (mm), the content estimate
    and the true count (containers), the reason it was not seen, the Observe's wall time
    (ms), and the content seen outside every container beside the truth."""

    sim_time: float
    object: str
    seen: bool
    error_mm: float | None = None
    sigma_mm: float | None = None
    content: int | None = None
    content_truth: int | None = None
    reason: str | None = None
    observe_ms: float | None = None
    outside: int | None = None
    """Content spheres the Observation saw outside every container (spilled in view)."""
    outside_truth: int | None = None
    """Content spheres truly in no container at that time."""


class CoverageSummary(msgspec.Struct, kw_only=True):
    """How much of the specification the run exercised (``roco spec coverage RUN``,
    services/spec_check/coverage.py, which makes it: the report shows it, it does not count
    it). ``exercised`` of ``items``; ``kinds`` per kind of item (protocol transitions,
    not-understood, time-outs, FSM states and arcs, content terms): (name, exercised, items);
    ``figure`` the figure's path relative to the run folder ("": none drawn); ``never`` the
    first items never taken; ``notes`` what could not be counted."""

    exercised: int
    items: int
    kinds: list[tuple[str, int, int]]
    figure: str = ""
    never: list[str] = []
    notes: list[str] = []


class RequirementRow(msgspec.Struct, kw_only=True):
    """One requirement of the specification traced to this run (a generalised paper Table 7:
    where Table 7 names the channels each event used, this names, per requirement, the
    channels serving it and whether the run did what it asks;
    services/spec_check/trace.py). ``depth``: 0 for the root; ``steps`` and ``channels``
    (``C2 (a_co–a_hi)``) serve it; ``evidence``: per property, its text and verdict in
    this run (``a_km answers a knowledge query: shown``), empty for a requirement with
    children; ``first_t``/``last_t``: the first and last event matched (s since the run
    start); ``tests``: the tests that name it; ``verdict``: shown, not exercised or
    violated; ``against``: why it is violated besides its properties."""

    id: str
    depth: int
    text: str
    steps: list[int] = []
    channels: list[str] = []
    evidence: list[str] = []
    first_t: float | None = None
    last_t: float | None = None
    tests: int = 0
    verdict: str = ""
    against: list[str] = []


class NoticeRow(msgspec.Struct, kw_only=True):
    """A notice an agent sent a_hi for the person (an inform of a notice protocol, or an L_HC
    ``Notice``: services/report/notices.py): when (``t``, s since the run start), who said it
    (``sender``), its ``severity`` and the things it is ``about`` (a ``Notice``'s; empty for
    another term), and ``text``, what a_hi tells the person."""

    t: float
    sender: str
    severity: str
    text: str
    about: list[str] = []


class Report(msgspec.Struct, kw_only=True):
    """The experiment report of one run folder (paper §5.7). ``notes`` lists what was
    missing or could not be read."""

    header: Header
    sizes: SizeStats
    channels: list[ChannelStats]
    matrix: AgentMatrix
    events: list[Event]
    plans: list[PlanPhase]
    content: ContentOutcome
    notes: list[str]
    control: TimingStats | None = None
    """ag_ex's control-loop deadline statistics (``ag_ex_timing.json``), if written."""
    commands: list[CommandRow] = []
    coordination: list[CoordinationEvent] = []
    faults: list[FaultRow] = []
    """Injected faults (docs/faults.md); empty when none was applied."""
    perception: list[PerceptionRow] = []
    clock: RobotClock = RobotClock()
    """Recorder time → robot time (services/report/robot_clock.py)."""
    """Each camera Observation's objects beside the truth; empty when the run perceived from
    the ground truth (ROCO_PERCEPTION=truth) or ag_ex wrote no log."""
    coverage: CoverageSummary | None = None
    """How much of the specification the run exercised, when the report's writer counted it."""
    requirements: list[RequirementRow] = []
    """The requirement tree traced to this run (empty: not traced; services/spec_check/trace.py)."""
    flags: list[LiveFlag] = []
    """The requirement properties the live monitor flagged violated during the run, in the
    order flagged (services/recorder/flags.py)."""
    notices: list[NoticeRow] = []
    """What agents told the person through a_hi, in order (services/report/notices.py)."""
    system: str = "RoCo"
    """The name of the system the run's specification specifies."""
    paper: bool = True
    """Whether that system is the paper's Robot Companion: the report then compares with the
    paper (§5.7) and has the kitchen's sections (planning, content, control loop, commands,
    perception); another system's report has its own channels and agents only."""
    channel_ends: dict[str, tuple[str, str]] = {}
    """Each channel of the specification with its two ends, in its order."""
