"""The event timeline of a run in the layout of paper Table 7 (time [s], event, channels).

Events are derived from the conversations of a pour run (see the module functions); times
are arrival times at the recorder, in s since the run start.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import msgspec

from services.report.load import Message
from services.report.model import Event, PlanPhase
from shared.fipa_codec.languages.l_ex import (
    CommandResult,
    Grasp,
    Observe,
    Release,
    Tilt,
)
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.languages.l_wm import WorldUpdate

ENV_GAP_S = 2.0
"""Environment updates (C5 observations, C6 informs to a_km) closer than this (s) form one
episode, as in Table 7's "293–315 a_km receives information about the modified environment"."""


def find_command(messages: Sequence[Message]) -> Message | None:
    """The human command: the first C2 ``request`` (a_hi → a_co, L_HC ``HumanCommand``)."""
    for m in messages:
        if m.is_("C2", None, "request"):
            return m
    return None


def find_outcome(messages: Sequence[Message]) -> Message | None:
    """The final outcome: the last C2 communicate carrying a ``CommandOutcome``, else the last
    C2 ``failure`` from a_co."""
    for m in reversed(messages):
        if m.channel == "C2" and isinstance(m.content, CommandOutcome):
            return m
    for m in reversed(messages):
        if m.is_("C2", "a_co", "failure"):
            return m
    return None


def command_text(command: Message | None) -> str:
    """The command's text ("" when not decodable)."""
    if command is not None and isinstance(command.content, HumanCommand):
        return command.content.text
    return ""


def timeline(
    messages: Sequence[Message],
    plans: Sequence[PlanPhase],
    command: Message | None,
    outcome: Message | None,
) -> list[Event]:
    """All events, sorted by start time (ties keep the order: knowledge, command, planning,
    execution, robot actions, environment, finish)."""
    if command is not None:
        cutoff = command.t
    elif plans:
        cutoff = plans[0].requested_t
    else:
        cutoff = math.inf
    events: list[Event] = []
    events += _initial_knowledge(messages, cutoff)
    if command is not None:
        text = command_text(command)
        said = f" “{text}”" if text else ""
        events.append(
            Event(
                start=command.t,
                text=f"a_co receives the command{said} from a_hi",
                channels=["C2"],
                kind="command",
            )
        )
    for p in plans:
        events += _plan_events(p)
    events += _executions(messages, plans)
    events += _robot_actions(messages, cutoff)
    events += _environment(messages, cutoff)
    if outcome is not None:
        events.append(
            Event(
                start=outcome.t,
                text=f"the task is finished: {_outcome_words(outcome)}",
                channels=["C2"],
                kind="finished",
            )
        )
    events.sort(key=lambda e: e.start)
    return events


def _outcome_words(outcome: Message) -> str:
    c = outcome.content
    if isinstance(c, CommandOutcome):
        word = "succeeded" if c.succeeded else "failed"
        return f"{word} ({c.detail})" if c.detail else word
    return "failed" if outcome.performative == "failure" else outcome.performative


def _channels(ms: Sequence[Message]) -> list[str]:
    return sorted({m.channel for m in ms})


def _initial_knowledge(messages: Sequence[Message], cutoff: float) -> list[Event]:
    pre = [m for m in messages if m.channel in ("C5", "C6") and m.t < cutoff]
    if not pre:
        return []
    return [
        Event(
            start=pre[0].t,
            end=pre[-1].t,
            text=f"a_km receives an initial knowledge about the environment ({len(pre)} communicates)",
            channels=_channels(pre),
            kind="initial_knowledge",
        )
    ]


def _num(x: float | None, unit: str, digits: int = 1) -> str:
    return "—" if x is None else f"{x:.{digits}f} {unit}"


def _plan_events(p: PlanPhase) -> list[Event]:
    k = p.index
    out = [
        Event(
            start=p.requested_t,
            text=f"a_co requests a_pl for the plan #{k}",
            channels=["C3"],
            kind="plan_request",
        )
    ]
    if p.c4_count:
        out.append(
            Event(
                start=p.requested_t,
                end=p.c4_last_t,
                text=f"a_pl generates the plan #{k}, and queries a_km: {p.c4_count} "
                f"communicates on C4, mean {_num(p.mean_kbps, 'kbps')}, "
                f"peak {_num(p.peak_kbps, 'kbps')}",
                channels=["C4"],
                kind="planning",
            )
        )
    if p.received_t is not None:
        if p.outcome.startswith("failed"):
            text, kind = f"a_pl answers plan request #{k}: {p.outcome}", "plan_failed"
        else:
            extra = ""
            if p.km_queries is not None:
                extra = f"; {p.km_queries} a_km queries, planning time {_num(p.planning_time_s, 's')}"
            text = f"a_co receives the generated plan #{k} from a_pl ({p.outcome}{extra})"
            kind = "plan_received"
        out.append(Event(start=p.received_t, text=text, channels=["C3"], kind=kind))
    return out


@dataclass
class _Execution:
    plan_id: str | None
    first: float
    last: float
    reports: int = 0
    last_state: str = ""


@dataclass
class _Executions:
    """The C1 record replayed message by message (:meth:`take`): a_co's plan requests name
    the conversations, its cancels are events, a_ta's informs extend their execution."""

    conv_plan: dict[str, str] = field(default_factory=dict)
    runs: dict[str, _Execution] = field(default_factory=dict)
    out: list[Event] = field(default_factory=list)

    def take(self, m: Message) -> None:
        if m.is_("C1", "a_co", "request") and isinstance(m.content, HierarchicalPlan):
            if m.conversation:
                self.conv_plan[m.conversation] = m.content.plan_id
        elif m.is_("C1", "a_co", "cancel"):
            self.out.append(
                Event(start=m.t, text="a_co cancels the plan execution", channels=["C1"], kind="cancel")
            )
        elif m.is_("C1", "a_ta", "inform"):
            self.report(m)

    def report(self, m: Message) -> None:
        """a_ta's state report ``m``, counted in its execution (begun by the first)."""
        status = m.content if isinstance(m.content, SWStatus) else None
        plan_id = self.conv_plan.get(m.conversation or "") or (status.plan_id if status else None)
        key = m.conversation if m.conversation in self.conv_plan else (plan_id or m.conversation or "?")
        run = self.runs.setdefault(key, _Execution(plan_id or None, m.t, m.t))
        run.last = m.t
        run.reports += 1
        if status is not None:
            run.last_state = status.state.value


def _execution_event(run: _Execution, index_of: Mapping[str | None, int]) -> Event:
    """One execution's span, named by its plan's number when the plan is known."""
    if run.plan_id in index_of:
        label = f"plan #{index_of[run.plan_id]}"
    else:
        label = f"plan {run.plan_id}" if run.plan_id else "plan"
    last = f", last: {run.last_state}" if run.last_state else ""
    return Event(
        start=run.first,
        end=run.last,
        text=f"a_ta executes the {label}, reports its state to a_co ({run.reports} state reports{last})",
        channels=["C1"],
        kind="execution",
    )


def _step_after(m: Message, step: str | None) -> str | None:
    """The HFSM step running after ``m``: none once a new plan starts or a plan ended, the step
    a_ta reports running."""
    if m.is_("C1", "a_co", "request"):
        return None  # a new plan starts
    if m.is_("C1", "a_ta", "inform") and isinstance(m.content, SWStatus):
        if m.content.state == SWState.RUNNING and m.content.step:
            return m.content.step
        if m.content.state in TERMINAL_SW_STATES:
            return None
    return step


def _answer_events(m: Message, cmd: msgspec.Struct | None, where: str) -> list[Event]:
    """ag_ex's answer ``m`` to command ``cmd``: what the robot did, and whether it touched
    itself (``where``: the step running)."""
    out: list[Event] = []
    described = _describe(cmd, m)
    if described is not None:
        kind, text = described
        out.append(Event(start=m.t, text=text + where, channels=["C5"], kind=kind))
    if isinstance(m.content, CommandResult) and m.content.self_contacts:
        name = type(cmd).__name__ if cmd is not None else m.content.command
        pairs = ", ".join(m.content.self_contacts)
        text = f"the robot touched itself during {name}: {pairs}{where}"
        out.append(Event(start=m.t, text=text, channels=["C5"], kind="self_contact"))
    return out


def _is_environment(m: Message, cutoff: float) -> bool:
    """A C6 inform a_ta → a_km, or a C5 observation, after ``cutoff``."""
    return m.t >= cutoff and (
        m.is_("C6", "a_ta", "inform")
        or (m.is_("C5", "ag_ex", "inform") and isinstance(m.content, Observation))
    )


def _episodes(members: Sequence[Message]) -> list[list[Message]]:
    """``members`` in runs whose gaps are at most :data:`ENV_GAP_S`."""
    episodes: list[list[Message]] = []
    for m in members:
        if episodes and m.t - episodes[-1][-1].t <= ENV_GAP_S:
            episodes[-1].append(m)
        else:
            episodes.append([m])
    return episodes


def _episode_event(ep: list[Message]) -> Event | None:
    """An episode's event, naming the objects its updates are about; None without a C6 inform."""
    updates = [m for m in ep if m.channel == "C6"]
    if not updates:
        return None
    names: list[str] = []
    for m in updates:
        if isinstance(m.content, WorldUpdate):
            names += [o.name for o in m.content.objects if o.name not in names]
    about = f": {', '.join(names)}" if names else ""
    return Event(
        start=ep[0].t,
        end=ep[-1].t if len(ep) > 1 else None,
        text=f"a_km receives information about the modified environment from a_ta "
        f"({len(updates)} update(s){about})",
        channels=_channels(ep),
        kind="environment",
    )


def _shaping_event(e: Mapping[str, object], t: float, t0: float) -> Event:
    """The shaping in force on the link from ``t``."""
    d, j, loss = (_float(e.get(k)) or 0.0 for k in ("delay_ms", "jitter_ms", "loss_pct"))
    text = f"the link brain–robot: {d:g} ± {j:g} ms each way, {loss:g} % loss ({e.get('how', '')})"
    return Event(start=max(0.0, t - t0), text=text, channels=[], kind="link_shaping")


def _executions(messages: Sequence[Message], plans: Sequence[PlanPhase]) -> list[Event]:
    """One span per executed plan: first to last C1 ``inform`` of a_ta (L_SW states), grouped
    by the C1 conversation a_co opened with the plan (else by ``SWStatus.plan_id``)."""
    index_of: dict[str | None, int] = {p.plan_id: p.index for p in plans if p.plan_id}
    replay = _Executions()
    for m in messages:
        replay.take(m)
    return replay.out + [_execution_event(run, index_of) for run in replay.runs.values()]


def _request_for(reply: Message, requests: Sequence[Message]) -> Message | None:
    """The C5 request ``reply`` answers: by in-reply-to, else conversation, else the latest."""
    irt = reply.comm.in_reply_to if reply.comm is not None else None
    for r in reversed(requests):
        if irt is not None and r.comm is not None and r.comm.reply_with == irt:
            return r
    for r in reversed(requests):
        if reply.conversation is not None and r.conversation == reply.conversation:
            return r
    return requests[-1] if requests else None


def _robot_actions(messages: Sequence[Message], cutoff: float) -> list[Event]:
    """Grasps, releases, tilts, observations and failed commands from ag_ex's C5 answers
    after ``cutoff``, named after the request they answer and the HFSM step running then."""
    requests: list[Message] = []
    step: str | None = None
    out: list[Event] = []
    for m in messages:
        step = _step_after(m, step)
        if m.is_("C5", "a_ta", "request"):
            requests.append(m)
        elif m.is_("C5", "ag_ex", "inform", "failure") and m.t >= cutoff:
            req = _request_for(m, requests)
            out += _answer_events(
                m, req.content if req is not None else None, f" (step {step})" if step else ""
            )
    return out


_ARM_ACTIONS: dict[type, tuple[str, str, str]] = {
    Grasp: ("grasp", "grasps", "grasp"),
    Release: ("release", "releases", "release"),
    Tilt: ("tilt", "tilts the held object (pouring)", "tilt"),
}
"""Per arm command: the event's kind, what the hand does, and the verb of its failure."""


def _arm_action(cmd: Grasp | Release | Tilt, *, ok: bool, reason: str) -> tuple[str, str]:
    """What a hand did, or failed to do and why."""
    kind, does, verb = next(v for c, v in _ARM_ACTIONS.items() if isinstance(cmd, c))
    if ok:
        return kind, f"{cmd.arm} hand {does}"
    return "action_failed", f"{cmd.arm} hand fails to {verb}: {reason}"


def _succeeded(reply: Message) -> tuple[bool, str]:
    """Whether ag_ex's answer says the command succeeded, and else why not."""
    result = reply.content
    ok = reply.performative == "inform" and not (isinstance(result, CommandResult) and not result.ok)
    reason = (result.reason if isinstance(result, CommandResult) else None) or reply.performative
    return ok, reason


def _describe(cmd: msgspec.Struct | None, reply: Message) -> tuple[str, str] | None:
    result = reply.content
    ok, reason = _succeeded(reply)
    if isinstance(result, Observation) or (isinstance(cmd, Observe) and ok):
        return "observation", _observed(result)
    if isinstance(cmd, Grasp | Release | Tilt):
        return _arm_action(cmd, ok=ok, reason=reason)
    if not ok:
        name = type(cmd).__name__ if cmd is not None else "an executor command"
        return "action_failed", f"{name} fails: {reason}"
    return None


def _observed(result: msgspec.Struct | None) -> str:
    if not isinstance(result, Observation) or not result.objects:
        return "the scene is observed"
    names = ", ".join(o.name for o in result.objects)
    text = f"{names} localised"
    for o in result.objects:
        if o.particles_inside is not None:
            text += f"; {o.particles_inside} of {result.total_particles} spheres in the {o.name}"
            if o.particles_inferred:
                text += f" ({o.particles_inferred} of them inferred, not seen)"
    return text


def _environment(messages: Sequence[Message], cutoff: float) -> list[Event]:
    """Episodes in which a_km learns about the changed environment: C6 informs a_ta → a_km
    (with the C5 observations they follow) after ``cutoff``, merged when closer than
    :data:`ENV_GAP_S`; an episode without a C6 inform is not listed."""
    episodes = _episodes([m for m in messages if _is_environment(m, cutoff)])
    return [e for e in map(_episode_event, episodes) if e is not None]


def link_events(entries: Sequence[Mapping[str, object]], t0: float) -> list[Event]:
    """Timeline rows of the link between two hosts (``link.jsonl``, services/hosts/link.py):
    the shaping in force from its start, and each partition from ``down`` to ``up`` (to the
    run's end, ``end`` None, when it was never mended). Times in s since ``t0``."""
    events: list[Event] = []
    down: float | None = None
    for e in entries:
        t = _float(e.get("t"))
        kind = e.get("event")
        if t is None:
            continue
        if kind == "shaping":
            events.append(_shaping_event(e, t, t0))
        elif kind == "down" and down is None:
            down = t
        elif kind == "up" and down is not None:
            text = f"the link brain–robot is cut ({t - down:.1f} s)"
            events.append(Event(start=down - t0, end=t - t0, text=text, channels=[], kind="link_down"))
            down = None
    if down is not None:
        events.append(
            Event(
                start=down - t0,
                text="the link brain–robot is cut (not mended)",
                channels=[],
                kind="link_down",
            )
        )
    return events


def _float(x: object) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else None


def conversation_events(messages: Sequence[Message]) -> list[Event]:
    """The timeline of a system other than the paper's (paper Table 7 layout, generalised): one
    row per conversation, from its first communicate to its last, saying who opened it, in which
    protocol, and the performatives it took in order (``a_op → a_so fipa-request: request,
    agree, inform``)."""
    by_conversation: dict[str, list[Message]] = {}
    for m in messages:
        key = m.conversation or f"#{m.rec.seq}"
        by_conversation.setdefault(key, []).append(m)
    events = []
    for group in by_conversation.values():
        first, last = group[0], group[-1]
        receiver = first.rec.receivers[0] if first.rec.receivers else "?"
        said = ", ".join(m.performative for m in group)
        events.append(
            Event(
                start=first.t,
                end=last.t if len(group) > 1 else None,
                text=f"{first.sender} → {receiver} {first.rec.protocol or 'no protocol'}: {said}",
                channels=sorted({m.rec.channel for m in group if m.rec.channel}),
                kind="conversation",
            )
        )
    return events
