"""A chaos run: process faults at random times while the robot carries out a
command, and a verdict on what the system kept.

:func:`chaos_scenario` makes a scenario (services/scenario/model.py): the command, then one
``fault`` step per service (each once, in a random order, or ``count`` draws), each some
random seconds after the one before, of a random kind (kill, pause, restart) and length. The
scenario runner injects them. :func:`verdict` reads the run folder's traffic record and
answers what a fault-tolerant system must keep:

- **task done** — every command ended as expected (a_hi's final report), and the world
  agrees (:class:`WorldCheck`): in the final world (below; without it, as ag_ex last observed
  it) each pour's target holds at least ``CONTENT_SHARE_REQUIRED`` of the content (90 %,
  shared/fipa_codec/languages/l_hc.py: the share the planner's goal and a_ta's content check ask
  for), counted by the simulation, not by the robot, and each object the plans a_ta ran put
  down stands where the plan put it (:func:`planned_places`); the report says which side
  disagreed;
- **no command lost** — every command got a final report;
- **nothing executed twice** — no request got two different final answers from the same
  agent (a retransmission answered from memory is byte-identical, so only a second
  execution gives a second, different answer), and the robot agrees: ag_ex's ledger of the
  commands its loop ran (``<run>/ag_ex_ledger.jsonl``, velma/executor/ledger.py) has no
  command started twice for one request and no request answered done that never ran
  (services/report/ledger.py);
- **no object dropped** — every movable object (jar, bowl, cup) stands higher than
  ``DROPPED_BELOW_M`` (the floor is z = 0; table top 0.75 m, cabinet shelves higher) in the
  final world: the scene the world process left when the fleet stopped (``<run>/world_final.f64``,
  read with ``velma.executor.checkpoint.observe_scene``), so an object that fell after the last
  observation is caught too. Without a readable final scene (``ROCO_WORLD=loop``) the objects as
  ag_ex last observed them during the run are judged instead (and the report says so); an
  object never observed counts as not known, and fails the check;
- **record intact** — the traffic record lost nothing, paired every record with its own
  payload and holds nothing twice (services/recorder/integrity.py), judged before the other
  questions read it: a record that is not intact could make them answer wrongly;
- **no agent raised** — every agent's ``handler_errors`` and ``behaviour_errors`` were 0
  when the commands ended, and no agent exited that the run did not fault (one that did was
  started again: services/scenario/runner.py; services/runtime/raised.py).
"""

from __future__ import annotations

import hashlib
import logging
import math
import random
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from services.hosts.fleet import ROUTERS
from services.recorder.integrity import Integrity
from services.recorder.record import read_link_events
from services.report.ledger import LedgerVerdict, judge_ledger
from services.report.load import Message, load_run
from services.report.world import judged_world
from services.scenario.model import (
    AGENTS,
    DEFAULT_COMMAND,
    FAULT_KINDS,
    MOVABLE,
    Fault,
    Scenario,
    Step,
    Trigger,
)
from services.scenario.runner import LINK, FaultRecord, ScenarioOutcome
from services.spec.model import default_spec
from shared.fipa_codec.languages.l_hc import CONTENT_SHARE_REQUIRED, HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_hfsm import Assert, ExpectedPosition, HierarchicalPlan, Perceive, PlanNode
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_sw import SWStatus

DROPPED_BELOW_M = 0.5
"""An object whose base is below this height (m, world z) has fallen off its furniture."""
CHAOS_FILE = "chaos.md"
log = logging.getLogger(__name__)
SERVICE_ORDER = default_spec().agent_names
"""Every agent, in the specification's order (the order a seed shuffles)."""
INFRASTRUCTURE = ("recorder", "router")
ALL = "all"
"""As a service list: every agent, the traffic recorder and the router."""
HOSTS_INFRASTRUCTURE = ("recorder", *ROUTERS, LINK)
"""What else can be faulted on two hosts (services/hosts/fleet.py): the recorder (the brain's),
each host's router, and the link between them (kind ``cut``)."""
HOSTS_DEFAULT = (*SERVICE_ORDER, *ROUTERS, LINK)
"""Faulted on two hosts unless told otherwise: every agent, both routers and the link."""
_FINAL = frozenset({"inform", "inform-ref", "failure", "refuse"})
_ONCE = frozenset({"fipa-request", "fipa-query"})
"""Protocols whose request gets one final answer (subscribe and coordinate stream many)."""


def _chosen_services(services: tuple[str, ...] | None, hosts: bool) -> tuple[str, ...]:
    """The services :func:`chaos_scenario` may fault (None: the default; ``("all",)``: the
    agents and the infrastructure, on two hosts with ``hosts``). Raises ValueError for an
    unknown one or none."""
    infrastructure = HOSTS_INFRASTRUCTURE if hosts else INFRASTRUCTURE
    if services is None:
        services = HOSTS_DEFAULT if hosts else SERVICE_ORDER
    if services == (ALL,):
        services = (*SERVICE_ORDER, *infrastructure)
    unknown = [s for s in services if s not in AGENTS | set(infrastructure)]
    if unknown or not services:
        known = ", ".join((*SERVICE_ORDER, *infrastructure))
        raise ValueError(f"cannot fault {', '.join(unknown) or 'nothing'} (services: {known}, or all)")
    return services


def _victims(rng: random.Random, services: tuple[str, ...], count: int | None) -> list[str]:
    """Each of ``services`` once in a random order (``count`` None), else ``count`` draws."""
    if count is None:
        victims = list(services)
        rng.shuffle(victims)
        return victims
    return [rng.choice(services) for _ in range(count)]


def chaos_scenario(
    seed: int,
    *,
    services: tuple[str, ...] | None = None,
    count: int | None = None,
    kinds: tuple[str, ...] = ("kill", "pause", "restart"),
    command: str = DEFAULT_COMMAND,
    gap_s: tuple[float, float] = (3.0, 8.0),
    down_s: tuple[float, float] = (0.5, 4.0),
    hosts: bool = False,
    cut_s: tuple[float, float] = (2.0, 6.0),
) -> Scenario:
    """The chaos scenario of ``seed``: ``command``, then faults of ``services`` — each once
    in a random order when ``count`` is None, else ``count`` random draws — each ``gap_s``
    (uniform, s) after the previous one, of one of ``kinds``, down for ``down_s`` (uniform,
    s). ``services``: default every agent (on two hosts :data:`HOSTS_DEFAULT`); it may be
    ``("all",)``: the agents, the recorder and the router. With
    ``hosts`` (the fleet on two hosts, services/hosts/fleet.py) the infrastructure is
    :data:`HOSTS_INFRASTRUCTURE` instead, ``all`` is the agents and all of it, and a fault of
    ``link`` is a cut of ``cut_s`` (uniform, s; over the routers' lease, services/hosts/
    fleet.py ``LEASE_MS``, the mesh link is closed and made again when the link returns).
    Raises ValueError for an unknown service or kind or an empty choice."""
    services = _chosen_services(services, hosts)
    bad = [k for k in kinds if k not in FAULT_KINDS]
    if bad or not kinds:
        raise ValueError(f"fault kinds are {', '.join(sorted(FAULT_KINDS))}, not {', '.join(bad) or 'none'}")
    rng = random.Random(seed)
    victims = _victims(rng, services, count)
    steps = [Step(say=command, expect="succeeded")]
    for victim in victims:
        if victim == LINK:
            kind, down = "cut", round(rng.uniform(*cut_s), 1)
        else:
            kind, down = rng.choice(kinds), round(rng.uniform(*down_s), 1)
        steps.append(
            Step(
                fault=Fault(service=victim, kind=kind, down_s=down),
                after=Trigger(seconds=round(rng.uniform(*gap_s), 1)),
            )
        )
    return Scenario(
        name=f"chaos (seed {seed})",
        description=f"{command!r} while {len(victims)} {'' if hosts else 'process '}faults hit "
        + ", ".join(victims)
        + (" (two hosts: brain and robot)" if hosts else ""),
        steps=tuple(steps),
    )


LAST_OBSERVED = "the last observations during the run"
"""Where the world is judged from without the world's final scene (``ROCO_WORLD=loop``)."""


@dataclass
class WorldCheck:
    """The world's side of "task done" (the module docstring): ``found``, what in the world
    contradicts the tasks, in words (empty: the world agrees); ``held``, what was checked and
    holds, in words; ``judged_on``, where the world comes from (the world's final scene, or
    :data:`LAST_OBSERVED`)."""

    found: list[str] = field(default_factory=list)
    held: list[str] = field(default_factory=list)
    judged_on: str = LAST_OBSERVED

    @property
    def agrees(self) -> bool:
        """Nothing in the world contradicts the tasks."""
        return not self.found

    def summary(self) -> str:
        """The world's answer in words: "agrees: the bowl holds 18 of 18 spheres; …" or
        "**disagrees**: …", then where it was judged from."""
        if self.agrees:
            return f"agrees: {'; '.join(self.held) or 'nothing to check'} (judged on {self.judged_on})"
        return f"**disagrees**: {'; '.join(self.found)} (judged on {self.judged_on})"


@dataclass
class Verdict:
    """What a chaos run kept (see the module docstring). ``reported_done``: a_hi's final
    reports say every command ended as expected; ``world``: whether the world agrees that the
    tasks are done; ``executed_twice``: requests
    answered twice differently, as "sender: conversation"; ``dropped``: objects found below
    ``DROPPED_BELOW_M``, with their height (m); ``last_observation``: every movable object's
    height is known; ``judged_on``: where the heights come from (the world's final scene, or the
    last observations during the run); ``record``: the traffic record's integrity; ``ledger``:
    ag_ex's ledger held against the record (its faults count as executed twice)."""

    reported_done: bool
    world: WorldCheck
    commands_lost: int
    executed_twice: list[str] = field(default_factory=list)
    dropped: dict[str, float] = field(default_factory=dict)
    last_observation: bool = False
    faults_during_command: int = 0
    faults: int = 0
    judged_on: str = LAST_OBSERVED
    record: Integrity = field(default_factory=Integrity)
    raised: str = ""
    """What the agents raised (services/runtime/raised.py ``raised_text``); "" when none did."""
    ledger: LedgerVerdict = field(default_factory=LedgerVerdict)

    @property
    def task_done(self) -> bool:
        """The messages say every command ended as expected, and the world agrees."""
        return self.reported_done and self.world.agrees

    @property
    def once(self) -> bool:
        """Nothing executed twice: neither two answers nor the ledger say so."""
        return not self.executed_twice and self.ledger.ok

    @property
    def ok(self) -> bool:
        return (
            self.record.intact
            and self.task_done
            and self.commands_lost == 0
            and self.once
            and not self.dropped
            and self.last_observation
            and not self.raised
        )


def _executed_twice(messages: Sequence[Message]) -> list[str]:
    """The requests answered twice, differently ("sender: conversation"): two final answers
    of a protocol that answers once, to the same message, with other contents or
    performatives."""
    answers: dict[tuple[str, str], set[bytes]] = defaultdict(set)
    where: dict[tuple[str, str], str] = {}
    for m in messages:
        if m.comm is None:
            continue
        if m.performative in _FINAL and m.comm.in_reply_to is not None and m.rec.protocol in _ONCE:
            k = (m.sender, m.comm.in_reply_to)
            answers[k].add(hashlib.blake2b(m.comm.content, digest_size=8).digest() + m.performative.encode())
            where[k] = m.conversation or "?"
    return sorted(f"{s}: {where[(s, r)]}" for (s, r), v in answers.items() if len(v) > 1)


def _heights(world: Observation | None) -> dict[str, float]:
    """Height (m, world z) of each movable object in ``world`` (none when None)."""
    return {o.name: o.pose.position[2] for o in world.objects if o.name in MOVABLE} if world else {}


def last_observed(messages: Sequence[Message]) -> Observation | None:
    """The world as last observed during the run (every L_SD ``Observation`` in the record, in
    order): each object as its last observation saw it, a container's ``particles_inside`` from
    the last observation that counted it, ``total_particles`` from the last that stated it; the
    last one's ``stamp``. None when nothing was observed."""
    objects: dict[str, ObjectObservation] = {}
    counted: dict[str, int] = {}
    total, stamp = 0, 0.0
    for m in messages:
        if m.comm is None or not isinstance(m.content, Observation):
            continue
        for o in m.content.objects:
            objects[o.name] = o
            if o.particles_inside is not None:
                counted[o.name] = o.particles_inside
        total, stamp = m.content.total_particles or total, m.content.stamp
    if not objects:
        return None
    seen = tuple(msgspec.structs.replace(o, particles_inside=counted.get(o.name)) for o in objects.values())
    return Observation(stamp=stamp, objects=seen, total_particles=total)


def command_goals(messages: Sequence[Message]) -> list[TaskAtom]:
    """The tasks the person's commands named (a_hi's C2 ``request`` of an L_HC
    ``HumanCommand`` to a_co: its ``goal``), in the order first asked, each once."""
    goals: list[TaskAtom] = []
    for m in messages:
        if (
            m.is_("C2", "a_hi", "request")
            and isinstance(m.content, HumanCommand)
            and m.content.goal not in goals
        ):
            goals.append(m.content.goal)
    return goals


def planned_places(messages: Sequence[Message]) -> dict[str, ExpectedPosition]:
    """Where the plans a_ta ran last put each object down: the expected position (world, m,
    with its tolerance and upright limit) of each placement-judging Perceive leaf (L_HFSM
    ``Perceive.judges``: the look after a set-down, services/agents/planner/hfsm.py) that a_ta
    began, the set-down before it having run. a_ta tells a_co each leaf it begins (C1, L_SW
    ``SWStatus.step``) of the plan it was sent (C1, ``HierarchicalPlan``; its safe stops'
    leaves too). An object a leaf begun later asserts held (L_HFSM ``Assert`` ``heldBy``) was
    taken again and has no place; a report of a plan not in the record is skipped."""
    plans: dict[str, dict[str, PlanNode]] = {}
    places: dict[str, ExpectedPosition] = {}
    for m in messages:
        if m.channel != "C1" or m.comm is None:
            continue
        if isinstance(m.content, HierarchicalPlan):
            plans.setdefault(m.content.plan_id, _leaves(m.content))
        elif isinstance(m.content, SWStatus) and m.content.step is not None:
            node = plans.get(m.content.plan_id, {}).get(m.content.step)
            _begun(places, node.action if node is not None else None)
    return places


def _leaves(plan: HierarchicalPlan) -> dict[str, PlanNode]:
    """The leaves of ``plan`` and of its safe stops, by path."""
    return dict([*plan.root.leaves(), *(leaf for stop in plan.safe_stops.values() for leaf in stop.leaves())])


def _begun(places: dict[str, ExpectedPosition], action: object) -> None:
    """What a leaf a_ta began changes in ``places``: a placement-judging look puts its objects
    where it expects them; an assertion that an object is held takes it from its place."""
    if isinstance(action, Perceive) and action.judges:
        places.update({e.object: e for e in action.expect})
    elif isinstance(action, Assert) and action.relation == "heldBy" and action.object:
        places.pop(action.subject, None)


def judge_world(
    world: Observation | None,
    goals: Sequence[TaskAtom],
    places: dict[str, ExpectedPosition],
    judged_on: str,
) -> WorldCheck:
    """Whether ``world`` (None: not known) shows the tasks done: the target of each pour in
    ``goals`` (``TaskAtom("pour", (source, target))``) holds at least ``CONTENT_SHARE_REQUIRED``
    of ``world.total_particles`` (the share a_ta's content check compares), and each object of
    ``places`` stands within its ``tolerance`` (m) of its ``position`` (world, m) and, when
    ``max_tilt`` is given, leans no more than that (rad) from upright (a_ta's judgement of a
    placement). Other goals are judged by the places alone. ``judged_on`` names the world."""
    check = WorldCheck(judged_on=judged_on)
    seen = {o.name: o for o in world.objects} if world is not None else {}
    total = world.total_particles if world is not None else 0
    for goal in goals:
        if goal.name == "pour" and len(goal.args) == 2:
            _judge_pour(check, seen.get(goal.args[1]), goal.args[1], total)
    for name, place in places.items():
        _judge_place(check, seen.get(name), name, place)
    return check


def _judge_pour(check: WorldCheck, target: ObjectObservation | None, name: str, total: int) -> None:
    """Whether the pour's ``target`` (``name``) holds its share of the ``total`` spheres."""
    if target is None or target.particles_inside is None or total <= 0:
        check.found.append(f"the {name}'s content is not known")
        return
    holds = f"the {target.name} holds {target.particles_inside} of {total} spheres"
    if target.particles_inside / total >= CONTENT_SHARE_REQUIRED:
        check.held.append(holds)
    else:
        check.found.append(f"{holds}, fewer than the {100 * CONTENT_SHARE_REQUIRED:.0f} % a pour needs")


def _judge_place(check: WorldCheck, o: ObjectObservation | None, name: str, place: ExpectedPosition) -> None:
    """Whether the object ``o`` (``name``) stands where the plan put it, upright enough."""
    if o is None:
        check.found.append(f"the {name} is not known (the plan put it down)")
        return
    wrong = []
    if (d := math.dist(o.pose.position, place.position)) > place.tolerance:
        wrong.append(f"the {name} stands {100 * d:.1f} cm from where the plan put it")
    if place.max_tilt is not None and (tilt := o.pose.tilt()) > place.max_tilt:
        wrong.append(f"the {name} leans {math.degrees(tilt):.0f}°")
    if wrong:
        check.found.extend(wrong)
    else:
        check.held.append(f"the {name} stands where the plan put it")


def verdict(run_dir: Path, outcome: ScenarioOutcome) -> Verdict:
    """Judge a chaos run from its outcome, its run folder's traffic record, the world's final
    scene and ag_ex's ledger (the six questions of the module docstring, the last from
    ``outcome``). Raises FileNotFoundError when ``run_dir`` is not a folder; a missing or
    corrupt traffic record reads as no traffic (services/report/load.py), a missing or unfit
    final scene as none (the world then as last observed), a missing ledger as an empty one;
    OSError when the ledger cannot be read."""
    run = load_run(run_dir)
    twice = _executed_twice(run.messages)
    judged = judged_world(run_dir)
    world, judged_on = last_observed(run.messages), LAST_OBSERVED
    if judged is not None:
        world, judged_on = judged[0], f"the final world ({judged[1]})"
    last = _heights(world)
    dropped = {name: round(z, 3) for name, z in last.items() if z < DROPPED_BELOW_M}
    return Verdict(
        reported_done=outcome.ok,
        world=judge_world(world, command_goals(run.messages), planned_places(run.messages), judged_on),
        commands_lost=sum(c.final is None for c in outcome.commands),
        executed_twice=twice,
        dropped=dropped,
        last_observation=set(last) == set(MOVABLE),
        faults_during_command=sum(f.during_command for f in outcome.faults),
        faults=len(outcome.faults),
        judged_on=judged_on,
        record=run.integrity,
        raised=outcome.raised_line(),
        ledger=judge_ledger(run_dir, run.messages),
    )


def final_heights(run_dir: Path) -> tuple[dict[str, float], str] | None:
    """Height (m, world z) of each movable object in ``judged_world``, and where it comes
    from; None without one."""
    judged = judged_world(run_dir)
    if judged is None:
        return None
    obs, source = judged
    return _heights(obs), source


QUESTIONS = (
    "task done",
    "no command lost",
    "nothing executed twice",
    "no object dropped",
    "record intact",
    "no agent raised",
)
"""The questions ``chaos.md`` answers, in its order (the rows of :func:`write_chaos_report`)."""


def _mark(ok: bool) -> str:
    return "yes" if ok else "**no**"


def _heading(scenario: Scenario, load: str) -> list[str]:
    """The report's title, the scenario's description and the ``load`` line (when given)."""
    lines = [f"# {scenario.name}", "", scenario.description, ""]
    return [*lines, load, ""] if load else lines


def write_chaos_report(
    run_dir: Path, scenario: Scenario, outcome: ScenarioOutcome, v: Verdict, load: str = ""
) -> Path:
    """Write ``<run>/chaos.md``: the faults injected (with the host each hit, and when the
    link was down, on two hosts), ``load`` (the busy processes beside the fleet,
    services/scenario/load.py ``BusyLoad.line``; "" leaves it out) and the verdict. Returns its
    path."""
    hosts = any(f.host is not None for f in outcome.faults)
    host = (" host |", "---|") if hosts else ("", "")
    lines = [
        *_heading(scenario, load),
        f"| t (s) |{host[0]} service | fault | down (s) | pids | alive again after (s) "
        "| during the command |",
        f"|---:|{host[1]}---|---|---:|---|---:|---|",
    ]
    for f in outcome.faults:
        lines.append(_fault_row(f))
    if hosts or (run_dir / "link.jsonl").exists():
        lines += ["", *link_down_lines(run_dir, outcome.started)]
    lines += [
        "",
        "| question | answer |",
        "|---|---|",
        _task_row(v),
        f"| no command lost | {_mark(v.commands_lost == 0)} ({v.commands_lost} lost) |",
        _once_row(v),
        f"| no object dropped | {_mark(not v.dropped and v.last_observation)} "
        + (
            ", ".join(f"{k} at z = {z} m" for k, z in v.dropped.items())
            if v.last_observation
            else "(not every object was observed)"
        )
        + f" (judged on {v.judged_on}) |",
        f"| record intact | {_mark(v.record.intact)} ({v.record.detail()}) |",
        f"| no agent raised | {_mark(not v.raised)} {v.raised} |",
        f"| faults during the command | {v.faults_during_command} of {v.faults} |",
        "",
        "Commands:",
        "",
        *[f"- {line}" for line in outcome.summary().splitlines()],
        "",
    ]
    path = run_dir / CHAOS_FILE
    path.write_text("\n".join(lines))
    return path


def _task_row(v: Verdict) -> str:
    """The "task done" row: what a_hi's reports said, then whether the world agrees."""
    reports = "done" if v.reported_done else "**not done**"
    return f"| task done | {_mark(v.task_done)} a_hi's reports: {reports}; the world: {v.world.summary()} |"


def _once_row(v: Verdict) -> str:
    """The "nothing executed twice" row: the requests answered twice, then the ledger's verdict."""
    answered = "".join(f"{s}; " for s in v.executed_twice)
    return f"| nothing executed twice | {_mark(v.once)} {answered}ag_ex's ledger: {v.ledger.summary()} |"


def _fault_row(f: FaultRecord) -> str:
    back = f"{f.back_after_s:.1f}" if f.back_after_s is not None else "never"
    host = f" {f.host} |" if f.host is not None else ""
    pids = f"{f.pid_before} → {f.pid_after}" if f.pid_before is not None else "–"
    return (
        f"| {f.t:.1f} |{host} {f.service} | {f.kind} | {f.down_s:.1f} | {pids} "
        f"| {back} | {'yes' if f.during_command else 'no'} |"
    )


def link_down_lines(run_dir: Path, started: float) -> list[str]:
    """When the link between the hosts was down, from the run folder's ``link.jsonl``
    (services/hosts/link.py), in s since ``started`` (POSIX time), and its shaping."""
    events = read_link_events(run_dir)
    lines, down = [], None
    for e in events:
        t = _num(e.get("t")) - started
        if e.get("event") == "shaping":
            lines.append(
                f"The link: {_num(e.get('delay_ms')):g} ± {_num(e.get('jitter_ms')):g} ms each way, "
                f"{_num(e.get('loss_pct')):g} % loss ({e.get('how', '?')}). When it was down:"
            )
        elif e.get("event") == "down":
            down = t
        elif e.get("event") == "up" and down is not None:
            lines.append(f"- link down from t = {down:.1f} s to t = {t:.1f} s ({t - down:.1f} s)")
            down = None
    if down is not None:
        lines.append(f"- link down from t = {down:.1f} s to the end of the run")
    if not any(line.startswith("- link down") for line in lines):
        lines.append("- the link was never down")
    return lines


def _num(x: object) -> float:
    return float(x) if isinstance(x, int | float) else 0.0
