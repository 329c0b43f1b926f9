"""A chaos run: process faults at random times while the robot carries out a
command, and a verdict on what the system kept.

:func:`chaos_scenario` makes a scenario (services/scenario/model.py): the command, then one
``fault`` step per service (each once, in a random order, or ``count`` draws), each some
random seconds after the one before, of a random kind (kill, pause, restart) and length. The
scenario runner injects them. :func:`verdict` reads the run folder's traffic record and
answers what a fault-tolerant system must keep:

- **task done** — every command ended as expected (a_hi's final report);
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
import random
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from services.fleet.launcher import load_launch_env
from services.hosts.fleet import ROUTERS
from services.recorder.integrity import Integrity
from services.recorder.record import read_link_events
from services.report.ledger import LedgerVerdict, judge_ledger
from services.report.load import Message, load_run
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
from shared.fipa_codec.languages.l_sd import Observation
from shared.settings import Settings

DROPPED_BELOW_M = 0.5
"""An object whose base is below this height (m, world z) has fallen off its furniture."""
CHAOS_FILE = "chaos.md"
MAX_SCENE_BYTES = 1 << 20
"""Largest final scene read (1 MiB; the kitchen's is 1.4 kB)."""
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


@dataclass
class Verdict:
    """What a chaos run kept (see the module docstring). ``executed_twice``: requests
    answered twice differently, as "sender: conversation"; ``dropped``: objects found below
    ``DROPPED_BELOW_M``, with their height (m); ``last_observation``: every movable object's
    height is known; ``judged_on``: where the heights come from (the world's final scene, or the
    last observations during the run); ``record``: the traffic record's integrity; ``ledger``:
    ag_ex's ledger held against the record (its faults count as executed twice)."""

    task_done: bool
    commands_lost: int
    executed_twice: list[str] = field(default_factory=list)
    dropped: dict[str, float] = field(default_factory=dict)
    last_observation: bool = False
    faults_during_command: int = 0
    faults: int = 0
    judged_on: str = "the last observations during the run"
    record: Integrity = field(default_factory=Integrity)
    raised: str = ""
    """What the agents raised (services/runtime/raised.py ``raised_text``); "" when none did."""
    ledger: LedgerVerdict = field(default_factory=LedgerVerdict)

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


def _last_heights(messages: Sequence[Message]) -> dict[str, float]:
    """Each movable object's height (m) at its last observation."""
    last: dict[str, float] = {}
    for m in messages:
        if m.comm is not None and isinstance(m.content, Observation):
            last.update({o.name: o.pose.position[2] for o in m.content.objects if o.name in MOVABLE})
    return last


def verdict(run_dir: Path, outcome: ScenarioOutcome) -> Verdict:
    """Judge a chaos run from its outcome, its run folder's traffic record and ag_ex's ledger
    (the six questions of the module docstring, the last from ``outcome``). Raises
    FileNotFoundError when ``run_dir`` is not a folder; a missing or corrupt traffic record reads
    as no traffic (services/report/load.py), a missing ledger as an empty one; OSError when the
    ledger cannot be read."""
    run = load_run(run_dir)
    twice = _executed_twice(run.messages)
    last = _last_heights(run.messages)
    final = final_heights(run_dir)
    judged_on = Verdict.judged_on
    if final is not None:
        last, judged_on = final[0], f"the final world ({final[1]})"
    dropped = {name: round(z, 3) for name, z in last.items() if z < DROPPED_BELOW_M}
    return Verdict(
        task_done=outcome.ok,
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


def final_world(run_dir: Path) -> Observation | None:
    """The ground truth of the world as the run left it (``judged_world``), None without one."""
    judged = judged_world(run_dir)
    return None if judged is None else judged[0]


def judged_world(run_dir: Path) -> tuple[Observation, str] | None:
    """The ground truth of the world as the run left it in ``run_dir`` (every known object's
    pose, containers' particle counts): the world process's final scene (velma/world/files.py
    ``FINAL_FILE``) for the scene the launch environment names (ROCO_SEED, ROCO_POSE_SEED): for
    judging a run, never for the agents; with where it comes from. None when there is none
    (``ROCO_WORLD=loop``), or it does not fit (logged)."""
    from velma.executor.checkpoint import observe_scene
    from velma.world.files import FINAL_FILE

    scene = run_dir / FINAL_FILE
    if not scene.is_file():
        return None
    env = load_launch_env(run_dir) or {}
    try:
        read = Settings.from_env(env, only=("seed", "pose_seed"))
        seed, pose_seed = read.seed, read.pose_seed
        if (size := scene.stat().st_size) > MAX_SCENE_BYTES:
            raise ValueError(f"{size} B: not a scene of the kitchen")
        return observe_scene(scene.read_bytes(), seed=seed, pose_seed=pose_seed), "the world's final scene"
    except (OSError, ValueError) as exc:
        log.warning("final world not judged from %s: %s", scene, exc)
        return None


def final_heights(run_dir: Path) -> tuple[dict[str, float], str] | None:
    """Height (m, world z) of each movable object in ``judged_world``, and where it comes
    from; None without one."""
    judged = judged_world(run_dir)
    if judged is None:
        return None
    obs, source = judged
    return {o.name: o.pose.position[2] for o in obs.objects if o.name in MOVABLE}, source


def _mark(ok: bool) -> str:
    return "yes" if ok else "**no**"


def write_chaos_report(run_dir: Path, scenario: Scenario, outcome: ScenarioOutcome, v: Verdict) -> Path:
    """Write ``<run>/chaos.md``: the faults injected (with the host each hit, and when the
    link was down, on two hosts) and the verdict. Returns its path."""
    hosts = any(f.host is not None for f in outcome.faults)
    host = (" host |", "---|") if hosts else ("", "")
    lines = [
        f"# {scenario.name}",
        "",
        scenario.description,
        "",
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
        f"| task done | {_mark(v.task_done)} |",
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
