"""What a run's traffic record holds of one agent: what it received and what it sent.

Read through services/report/load.py (``traffic.jsonl`` with ``traffic.msgpack``, integrity
checked, copies marked), as ``roco spec verify`` reads it. The inputs come in the order the agent
received them as far as the record tells, not in the order they reached the recorder: each
publisher reaches the recorder over a path of its own (agents linked directly, the recorder
through the router; on two hosts across the link, or beside the sender), and the recorder may
see a communicate after the agent had answered it. Each input is taken as reaching the agent
when its publisher's timestamp and the path from its sender to the agent say
(:attr:`Recorded.reached`, :class:`Paths`), then in causal order (services/recorder/causal.py:
an answer after what it answers, then the senders' clocks across a conversation).

A record made by a recorder that was restarted during the run (docs/recovery.md) holds what the
publishers' caches gave the next incarnation, stamped with the times they were sent (``late``),
and may hold a communicate twice: each is taken once, by its identity (publisher and sequence
number, and place in a batch). What the record lacks by the publishers' sequence numbers
(services/recorder/integrity.py, gaps) is counted per agent, in and out: an agent with a
communicate of its own missing cannot be reproduced from the record, and its replay says so
(:attr:`AgentRecord.missing`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from services.recorder.causal import causal_order, send_order
from services.recorder.integrity import Integrity
from services.recorder.record import read_hosts
from services.report.load import Message, RunData, load_run
from services.runtime import keys
from shared.fipa_codec import Communicate


@dataclass(frozen=True)
class Recorded:
    """One recorded communicate: ``seq`` its index in the traffic record, ``t`` when it crossed
    Zenoh (POSIX s, its arrival at the recorder), ``sent`` its sender's timestamp when it carried
    one (else ``t``), the ``key`` it was put on, the communicate ``comm``, ``copy`` True for
    a copy of an earlier one on the same key (retransmitted, or answered again to a copy:
    services/runtime/dedup.py), and for an input ``reached``: when it reached the agent as the
    record tells (its sender's timestamp and the path to the agent: :class:`Paths`; None: ``t``)."""

    seq: int
    t: float
    sent: float
    key: str
    comm: Communicate
    copy: bool = False
    reached: float | None = None

    @property
    def came(self) -> float:
        """When the input reached the agent (POSIX s): :attr:`reached`, else its arrival ``t``."""
        return self.t if self.reached is None else self.reached

    @property
    def line(self) -> str:
        """``a_pl → a_co inform (fipa-request)``: who sent what to whom."""
        parsed = keys.parse_fipa_key(self.key)
        protocol = f" ({self.comm.protocol})" if self.comm.protocol else ""
        return f"{parsed.sender} → {parsed.receiver} {self.comm.performative.value}{protocol}"


@dataclass(frozen=True)
class Paths:
    """How long a communicate or a liveliness token took from one process of the run to
    another: ``host`` the host of each process (``hosts.json`` of a run on several hosts; none:
    one host, where every path is about none), ``link`` the delay (s) between two hosts, as the
    record shows it (:func:`paths`). A process no host names is taken as the recorder's
    neighbour."""

    host: dict[str, str] = field(default_factory=dict)
    link: float = 0.0

    def where(self, name: str) -> str:
        """The host of process ``name`` (the recorder's when none is named)."""
        return self.host.get(name, self.host.get(RECORDER, ""))

    def between(self, a: str, b: str) -> float:
        """The delay (s) from process ``a`` to process ``b``: none on one host, else the link's."""
        return 0.0 if self.where(a) == self.where(b) else self.link


RECORDER = "recorder"
"""The traffic recorder's name among the processes (services/recorder/recorder.py)."""


@dataclass
class AgentRecord:
    """The record of ``agent`` in one run: ``t0`` when the run began and ``end`` the last time
    in the record (POSIX s); ``inputs``, the communicates to it, in causal order (module
    docstring); ``outputs``, those from it per key (one receiver and channel each) in the order it
    sent them (its publisher's sequence numbers), copies included; ``notes`` on what of the
    record could not be used."""

    agent: str
    t0: float
    end: float
    inputs: list[Recorded] = field(default_factory=list)
    outputs: dict[str, list[Recorded]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    sessions: int = 1
    """How many sessions (publishers' Zenoh sessions) the agent sent from: more than one when
    it was restarted during the run."""
    missing_inputs: int = 0
    """Communicates to the agent missing from the record (by their publishers' sequence
    numbers)."""
    missing_outputs: int = 0
    """Communicates from the agent missing from the record."""
    restarts: list[float] = field(default_factory=list)
    """When each recorder incarnation after the first was listening, at the latest (s since
    ``t0``: its first communicate that was not recovered from a cache)."""
    duplicates: int = 0
    """Communicates of the agent recorded twice (the same publisher and sequence number), each
    taken once."""
    paths: Paths = field(default_factory=Paths)
    """How long communicates and tokens took between the run's processes."""
    lateness: float = 0.0
    """The most time (s) the recorder took to see a communicate of the run after it was sent:
    how late it may see anything (a liveliness token too) after the agents did."""

    @property
    def missing(self) -> str | None:
        """Why the agent cannot be reproduced from the record, None when nothing of it is
        missing: ``2 inputs missing from the record (recorder restarted at 12.345 s)``."""
        parts = [
            f"{n} {what}{'' if n == 1 else 's'}"
            for n, what in ((self.missing_inputs, "input"), (self.missing_outputs, "output"))
            if n
        ]
        if not parts:
            return None
        when = ", ".join(f"{t:.3f} s" for t in self.restarts)
        restarted = f" (recorder restarted at {when})" if self.restarts else ""
        return f"{' and '.join(parts)} missing from the record{restarted}"

    @property
    def start(self) -> float:
        """When the agent was last seen not yet to have said or heard anything (POSIX s): its
        first communicate's time, the sender's timestamp for one it sent (it ran by then, and
        what it sends as it starts, a_km's subscription, goes at once)."""
        first = [min(item.came for item in self.inputs)] if self.inputs else []
        first += [items[0].sent for items in self.outputs.values() if items]
        return min(first, default=self.t0)


def agent_record(run_dir: Path, agent: str, causal: bool = True) -> AgentRecord:
    """The record of ``agent`` in ``run_dir``, its inputs in the order and at the times they
    reached it (module docstring; ``causal`` False: in the order and at the times they reached
    the recorder). Raises FileNotFoundError (naming the path) when the folder does not exist and
    ValueError when its record holds no communicate to or from ``agent``; anything else missing
    or corrupt becomes a note."""
    run = load_run(run_dir)
    out = AgentRecord(agent, run.t0, max((m.rec.t for m in run.messages), default=run.t0))
    out.notes = list(run.notes)
    out.paths = paths(read_hosts(run_dir), run.messages)
    out.lateness = max((d for m in run.messages if (d := _delay(m)) is not None), default=0.0)
    mine = [m for m in run.messages if _way(m, agent)]
    unusable = _take(_ordered(mine, agent, out.paths, causal), agent, out, out.paths if causal else None)
    if not out.inputs and not out.outputs:
        raise ValueError(f"the traffic record of {run_dir} holds no communicate to or from {agent}")
    _lost(run.integrity, agent, out)
    out.restarts = restarts(run)
    _noted(out, unusable)
    return out


def _noted(out: AgentRecord, unusable: int) -> None:
    """Note in ``out`` what of the agent's record was left out or taken once."""
    if unusable:
        out.notes.append(f"{unusable} communicate(s) of {out.agent} without a payload that decodes: left out")
    if out.duplicates:
        out.notes.append(f"{out.duplicates} communicate(s) of {out.agent} recorded twice: taken once")


def _take(messages: list[Message], agent: str, out: AgentRecord, paths: Paths | None) -> int:
    """Put into ``out`` the communicates of ``messages`` to ``agent`` (inputs, in the order
    given, each reaching the agent when its timestamp and ``paths`` say; None: when the recorder
    saw it) and from it (outputs, per key in the order sent), each once; returns how many of
    them have no payload that decodes."""
    sent: list[tuple[tuple[int, int, int], Recorded]] = []
    sessions: dict[str, int] = {}
    seen: set[tuple[str, int, int]] = set()
    unusable = 0
    for m in messages:
        way = _way(m, agent)
        if not way:
            continue
        if _again(m, seen):
            out.duplicates += 1
            continue
        reached = _reached(m, agent, paths) if way == "in" and paths is not None else None
        item = _recorded(m, reached)
        if item is None:
            unusable += 1
        elif way == "in":
            out.inputs.append(item)
        else:
            sent.append((_sent_order(m, sessions), item))
    for _, item in sorted(sent, key=lambda x: x[0]):
        out.outputs.setdefault(item.key, []).append(item)
    out.sessions = max(1, len(sessions))
    return unusable


def _again(m: Message, seen: set[tuple[str, int, int]]) -> bool:
    """Whether ``m`` is a communicate already taken (the same publisher, sequence number and
    place in a batch, in ``seen``); a communicate without them is never one."""
    if m.rec.source is None or m.rec.sn is None:
        return False
    identity = (m.rec.source, m.rec.sn, m.rec.part)
    if identity in seen:
        return True
    seen.add(identity)
    return False


def _lost(checked: Integrity, agent: str, out: AgentRecord) -> None:
    """Count into ``out`` the communicates to and from ``agent`` that the record lacks (its
    gaps by sequence number: services/recorder/integrity.py)."""
    for gap in checked.gaps:
        try:
            parsed = keys.parse_fipa_key(gap.key)
        except ValueError:
            continue
        if parsed.receiver == agent:
            out.missing_inputs += gap.count
        elif parsed.sender == agent:
            out.missing_outputs += gap.count


def restarts(run: RunData) -> list[float]:
    """When each recorder incarnation after the first of ``run`` was listening, at the latest:
    the time of its first communicate not recovered from a publisher's cache (s since the run
    began), in the order the incarnations first wrote."""
    first: dict[str, float] = {}
    for m in run.messages:  # in time order
        if not m.rec.late:
            first.setdefault(m.rec.incarnation, m.rec.t - run.t0)
    return [first[i] for i in run.integrity.incarnations[1:] if i in first]


def paths(hosts: dict[str, str], messages: list[Message]) -> Paths:
    """The paths of a run whose processes ran on ``hosts`` (process → host; none: one host)
    with the traffic ``messages``: the link's delay is the least with which the recorder saw a
    communicate from another host than its own after it was sent (its arrival less its
    publisher's timestamp): what the recorder took more for others was its own load."""
    here = hosts.get(RECORDER)
    across = [
        d
        for m in messages
        if hosts.get(m.rec.key_sender or m.rec.sender, here) != here
        and (d := _delay(m)) is not None
        and d > 0
    ]
    return Paths(dict(hosts), min(across, default=0.0))


def _delay(m: Message) -> float | None:
    """How long after it was sent the recorder saw ``m`` (s), None when that is not known (no
    publisher's timestamp, or a copy from a publisher's cache, recorded at the time it was
    sent)."""
    if m.rec.t_sent is None or m.rec.late:
        return None
    return m.rec.t - m.rec.t_sent


def _ordered(messages: list[Message], agent: str, paths: Paths, causal: bool) -> list[Message]:
    """``messages`` (to and from ``agent``) in the order the agent saw them (``causal`` False:
    as given): each it sent when it sent it, each it received when it reached it
    (:func:`_reached`), then in causal order: answers after what they answer, then the senders'
    clocks across a conversation (services/recorder/causal.py)."""
    if not causal:
        return messages
    seen = sorted(messages, key=lambda m: _seen_at(m, agent, paths))
    return send_order(causal_order(seen)[0])[0]


def _seen_at(m: Message, agent: str, paths: Paths) -> float:
    """When ``agent`` sent ``m`` (its timestamp) or ``m`` reached it (:func:`_reached`)."""
    if _way(m, agent) == "out":
        return m.rec.t_sent if m.rec.t_sent is not None else m.rec.t
    return _reached(m, agent, paths)


def _reached(m: Message, agent: str, paths: Paths) -> float:
    """When input ``m`` reached ``agent``: its publisher's timestamp and the path from its
    sender (``paths``); without a timestamp, when the recorder saw it; a copy from a publisher's
    cache at the time it was sent (the recorder's time for it: it reached the agent then, or was
    lost to it too)."""
    if m.rec.t_sent is None or m.rec.late:
        return m.rec.t
    return m.rec.t_sent + paths.between(m.rec.key_sender or m.rec.sender, agent)


def _way(m: Message, agent: str) -> str:
    """``in`` for a communicate to ``agent``, ``out`` for one from it, else empty."""
    try:
        parsed = keys.parse_fipa_key(m.rec.key)
    except ValueError:
        return ""
    return "in" if parsed.receiver == agent else "out" if parsed.sender == agent else ""


def _sent_order(m: Message, sessions: dict[str, int]) -> tuple[int, int, int]:
    """Where ``m`` comes among what its sender sent on its key: its session (numbered as they
    first appear in ``sessions``), then its publisher's sequence number and place in a batch
    (the record's order where it has none)."""
    session = sessions.setdefault((m.rec.source or "").partition(":")[0], len(sessions))
    return (session, m.rec.sn, m.rec.part) if m.rec.sn is not None else (session, m.rec.seq, 0)


def _recorded(m: Message, reached: float | None) -> Recorded | None:
    """``m`` as the replay takes it; an input with when it ``reached`` the agent (None: when
    the recorder saw it)."""
    if m.comm is None:
        return None
    sent = m.rec.t_sent if m.rec.t_sent is not None else m.rec.t
    return Recorded(m.rec.seq, m.rec.t, sent, m.rec.key, m.comm, copy=m.copy_of is not None, reached=reached)
