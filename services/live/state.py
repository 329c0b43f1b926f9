"""What the live view shows, folded from the run's observations (no I/O; thread-safe).

Feed it communicates (:meth:`LiveState.communicate`: key ``roco/fipa/<channel>/<sender>/<receiver>``
and msgpack bytes), ag_ex's state (:meth:`LiveState.robot_state`: msgpack ``RobotSnapshot``
bytes of ``roco/state/ag_ex``) and liveliness changes (:meth:`LiveState.alive`); read it with
:meth:`LiveState.progress`, a frozen :class:`Progress`. Times are seconds: ``wall`` on the
caller's clock (``time.monotonic``), ``sim`` on ag_ex's simulation clock."""

from __future__ import annotations

import threading
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any

import msgspec

from services.runtime import keys
from shared.fipa_codec import Communicate, DecodeError, Performative, decode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, Notice
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.languages.told import told
from velma.executor.timing import TimingStats


class _StateGlance(msgspec.Struct):
    """The two fields of ag_ex's ``RobotSnapshot`` (velma/executor/state.py) the view shows;
    msgspec skips the others (joints, poses, wrenches) without building them."""

    sim_time: float
    timing: TimingStats | None = None


@dataclass(frozen=True)
class PlanInfo:
    """A plan a_pl made: ``index`` k (the task's k-th plan, L_HFSM ``plan_index``), whether it
    is ``complete`` (False: it ends with sensing, plan k + 1 follows) and its leaf ``steps``
    (HFSM paths, in execution order: what a_ta reports in L_SW ``step``)."""

    plan_id: str
    index: int
    complete: bool
    steps: tuple[str, ...]

    @property
    def of(self) -> str:
        """n of "plan k of n": k when complete, "≥ k+1" while another plan must follow."""
        return str(self.index) if self.complete else f"≥ {self.index + 1}"


@dataclass(frozen=True)
class Progress:
    """One reading of the live state (see :class:`LiveState`). ``step_place`` is (i, n), the
    running step's 1-based place among the plan's n steps, None for a step outside the plan
    (a safe stop's); ``sim_rate`` the simulated seconds per wall second since the first state
    seen; ``overrun_share`` the loop's overruns / cycles since it started (0..1)."""

    command: str | None
    commands: int
    outcome: str | None
    plan: PlanInfo | None
    step: str | None
    step_place: tuple[int, int] | None
    sw_state: str | None
    alive: frozenset[str]
    expected: tuple[str, ...]
    wall_s: float
    sim_s: float | None
    sim_rate: float | None
    overrun_share: float | None
    overruns: int
    cycles: int
    notice: str | None = None
    """The last notice an agent sent a_hi for the person (an inform of a notice protocol, or
    carrying an L_HC ``Notice``): its sender, a Notice's severity and what a_hi tells the person
    (shared/fipa_codec/languages/told.py), ``a_wt (warning): the jar tipped over``; None: none
    yet."""
    notices: int = 0
    """Notices seen so far."""


@dataclass
class LiveState:
    """The fold; ``expected`` the agents that should be alive, ``started`` the wall time
    (caller's clock, s) the run started, ``notice_protocols`` the specification's notice
    protocols (services/spec/notices.py: their informs are notices to the person, as are the
    informs carrying an L_HC ``Notice``)."""

    expected: tuple[str, ...]
    started: float
    notice_protocols: Collection[str] = ()
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _commands: list[str] = field(default_factory=list)
    _outcome: str | None = None
    _plan_index: dict[str, int] = field(default_factory=dict)  # task_id → last plan_index asked
    _plans: dict[str, PlanInfo] = field(default_factory=dict)  # plan_id → plan
    _last_plan: str | None = None
    _running_plan: str | None = None
    _step: str | None = None
    _sw_state: str | None = None
    _alive: set[str] = field(default_factory=set)
    _sim: float | None = None
    _first: tuple[float, float] | None = None  # (wall, sim) of the first state seen
    _last_wall: float | None = None
    _timing: TimingStats | None = None
    _notice: str | None = None
    _notices: int = 0

    def communicates(self, key: str, payload: bytes) -> None:
        """Take one sample: one communicate or a batch of them (shared/fipa_codec/batch.py)."""
        for communicate in unpack(payload):
            self.communicate(key, communicate)

    def communicate(self, key: str, payload: bytes) -> None:
        """Take one communicate; anything that is not one of the view's is ignored."""
        try:
            sender = keys.parse_fipa_key(key).sender
            msg = decode(payload)
            content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
        except (ValueError, DecodeError, ContentError):
            return
        with self._lock:
            if content is not None and self._is_notice(msg, content):  # said by its sender (the key's)
                self._notices += 1
                self._notice = f"{sender}{_severity(content)}: {_told(content)}"
                return
            for kind, take in _TAKES:
                if isinstance(content, kind):
                    take(self, content)
                    break

    def _is_notice(self, msg: Communicate, content: msgspec.Struct) -> bool:
        return isinstance(content, Notice) or (
            msg.performative is Performative.INFORM and msg.protocol in self.notice_protocols
        )

    def _command(self, content: HumanCommand) -> None:
        self._commands.append(content.text)
        self._outcome = None

    def _network(self, content: GroundTaskNetwork) -> None:
        self._plan_index[content.task_id] = content.plan_index

    def _plan(self, content: HierarchicalPlan) -> None:
        """A plan, the first time it is seen (its index: the request it answers)."""
        if content.plan_id in self._plans:
            return
        steps = tuple(path for path, _ in content.root.leaves())
        index = self._plan_index.get(content.task_id, 1)
        self._plans[content.plan_id] = PlanInfo(content.plan_id, index, content.complete, steps)
        self._last_plan = content.plan_id

    def _status(self, content: SWStatus) -> None:
        self._sw_state = content.state.value
        if content.plan_id:
            self._running_plan = content.plan_id
        if content.step:
            self._step = content.step

    def _command_outcome(self, content: CommandOutcome) -> None:
        self._outcome = f"{'succeeded' if content.succeeded else 'failed'}: {content.detail}"

    def robot_state(self, payload: bytes, wall: float) -> None:
        """Take one ``roco/state/ag_ex`` sample received at ``wall``; undecodable: ignored."""
        try:
            glance = msgspec.msgpack.decode(payload, type=_StateGlance)
        except (msgspec.DecodeError, msgspec.ValidationError):
            return
        with self._lock:
            if self._first is None or glance.sim_time < (self._sim or 0.0):  # first, or ag_ex restarted
                self._first = (wall, glance.sim_time)
            self._sim, self._last_wall = glance.sim_time, wall
            if glance.timing is not None:
                self._timing = glance.timing

    def alive(self, agent: str, alive: bool) -> None:
        """A liveliness token ``roco/alive/<agent>`` appeared (True) or went (False)."""
        with self._lock:
            (self._alive.add if alive else self._alive.discard)(agent)

    def progress(self, now: float) -> Progress:
        """The state at wall time ``now`` (the caller's clock)."""
        with self._lock:
            plan = self._shown_plan()
            t = self._timing
            return Progress(
                command=self._commands[-1] if self._commands else None,
                commands=len(self._commands),
                outcome=self._outcome,
                plan=plan,
                step=self._step,
                step_place=self._place(plan),
                sw_state=self._sw_state,
                alive=frozenset(self._alive),
                expected=self.expected,
                wall_s=now - self.started,
                sim_s=self._sim,
                sim_rate=self._rate(),
                overrun_share=t.overrun_share if t is not None else None,
                overruns=t.overruns if t is not None else 0,
                cycles=t.cycles if t is not None else 0,
                notice=self._notice,
                notices=self._notices,
            )

    def _shown_plan(self) -> PlanInfo | None:
        """The plan running, else the last one received (None: no plan yet)."""
        plan_id = self._running_plan if self._running_plan in self._plans else self._last_plan
        return self._plans.get(plan_id) if plan_id is not None else None

    def _place(self, plan: PlanInfo | None) -> tuple[int, int] | None:
        """Where the current step is in ``plan``: (i, n), or None when it is not one of its."""
        if plan is None or self._step not in plan.steps:
            return None
        return (plan.steps.index(self._step) + 1, len(plan.steps))

    def _rate(self) -> float | None:
        """Simulated seconds per wall second since the first state sample (None: too early)."""
        if self._first is None or self._last_wall is None or self._sim is None:
            return None
        dt = self._last_wall - self._first[0]
        return (self._sim - self._first[1]) / dt if dt > 0.5 else None


_TAKES: tuple[tuple[type, Callable[[LiveState, Any], None]], ...] = (
    (HumanCommand, LiveState._command),
    (GroundTaskNetwork, LiveState._network),
    (HierarchicalPlan, LiveState._plan),
    (SWStatus, LiveState._status),
    (CommandOutcome, LiveState._command_outcome),
)
"""What :meth:`LiveState.communicate` takes from a content of each kind (the first that fits)."""


def _severity(content: msgspec.Struct) -> str:
    """`` (warning)`` for a Notice (its severity); empty for another term."""
    return f" ({content.severity.value})" if isinstance(content, Notice) else ""


def _told(content: msgspec.Struct) -> str:
    """What a_hi tells the person of ``content`` (told.py); its string form when its own
    ``told()`` fails."""
    try:
        return told(content)
    except Exception:  # a term's own told() is the sender's code: any error of it
        return told(str(content))
