"""The replay of one agent: its recorded input fed to a fresh instance, its output compared.

The agent is built as its process builds it (the implementation the specification names), on
an in-memory bus, with neither the run folder nor a viewer, its kept state (and a_km's
knowledge store) in fresh folders of the replay's own: it starts as in the run, with nothing
kept. Every other agent's liveliness token is on the bus when the agent saw it appear and go
away, as the presence record tells by its time and its cause (services/replay/presence.py). The
driver owns the agent's time (:class:`~services.replay.sources.ReplaySources`) and runs its
elementary actions on its own thread (``Engine.drive``): the agent starts at its first
communicate's recorded time (``AgentRecord.start``), the clock moves to the time each input
reached the agent (``Recorded.came``: its sender's timestamp and path, not the time the recorder
saw it, which may be after the agent had answered it), or first to whatever time the agent waits
for before it (a period, a reply-by deadline, a retransmission), and stands still while the
agent computes. After the last input the clock runs on to the record's end. Each communicate
the agent sends is compared at once with the next one it sent on that key in the run
(services/replay/compare.py), which pairs their identifiers: the inputs that follow carry the
replayed identifiers where they answer the agent.

The inputs come in causal order (services/replay/record.py), and an input waits until the
replayed agent has sent what came before it in the run, then goes in at once: the agent's
outputs are made in the replay, so only the replay knows when it has sent them. Before an input
came (:meth:`_Replay.waits`):

- the communicate of the agent's it answers (its in-reply-to names the reply-with of one the
  agent sent in the run, in the same conversation-id: FIPA SC00061 §2.4);
- every communicate the agent sent to the input's sender before the input was sent (the
  record's send timestamps, ``Recorded.sent``), but one that answers the input: the sender had
  it, or it crossed the input on its way, and either way the agent had sent it before the input
  reached it. An answer does not name all of that: each of a_ta's informs on a plan's progress
  (coordinate protocol) answers a_co's request, yet a_ta sends the next only once a_co's confirm
  of the previous one has come, and a_hi's next command follows a_co's outcome of the last.

The send times are read on one clock: a run on several hosts trusts theirs to agree better than
an agent takes to answer. An input whose predecessors the replayed agent never sends goes in
after the last input.

When an input reached the agent is known within a window only: from when its sender's timestamp
and path say to when the recorder saw it. The replay takes the first; when it then differs, it is
made again with each input of such a window that began before the first difference (the nearest
first, :data:`MAX_ORDERS` of them) taken at the other end, as the agent's timer (a reply-by
deadline) may have come before it or after; then with each peer's token that appeared before
the first difference (or within the record's lateness after it: a token carries no timestamp)
taken that lateness earlier, as the agent's timer may have fired just after it, not before
(tests/replay/fixtures/timer_beside_token). An order that reproduces the run is one the record
allows, and the replay says which it took; when the replay differs in each order tried and the
differences depend on the order, it says it cannot decide that order
(:attr:`ReplayResult.undecided`) instead of reporting the differences of one.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from bisect import bisect_left
from collections import defaultdict, deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from services.recorder.presence import read_presence
from services.replay.compare import Difference, IdMap, compare
from services.replay.presence import Change, Timeline, timeline
from services.replay.record import AgentRecord, Recorded, agent_record
from services.replay.sources import ReplaySources
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.counters import read_counters
from services.runtime.dedup import wire_digest
from services.runtime.main import agent_class
from services.runtime.memory_transport import MemoryBus, MemoryTransport
from services.runtime.transport import Callback
from services.spec.model import SpecError, SystemSpec, default_spec
from shared.fipa_codec import Communicate, DecodeError, decode, encode
from shared.settings import Settings

UNSET = ("run_dir", "hooks", "rerun")
"""Settings (shared/settings.py) unset while the agent is replayed: it neither reads nor writes
the run folder, nor records for a viewer."""
KEPT = ("state_dir", "km_store")
"""Settings pointed at fresh folders of the replay's own while the agent is replayed: it keeps
its state (and a_km its knowledge) on disk as in the run, starting with nothing. (On disk
matters: the rows of a SPARQL query without ORDER BY come in the store's order, which differs
between Oxigraph's store on disk and in memory.)"""
TROUBLE = (
    "behaviour_errors",
    "handler_errors",
    "send_violations",
    "rejected",
    "protocol_violations",
    "deadline_failures",
)
"""The replayed agent's counters (services/runtime/engine.py) the result reports when not 0."""
MAX_STEPS = 1_000_000
"""Steps the agent may take without input before the replay gives up on it (it never blocks)."""
MAX_ORDERS = 3
"""Inputs whose time the record leaves open that a replay that differs tries at the other end of
their window (module docstring), the nearest its first difference first."""
ORDER_TOLERANCE_S = 0.001
"""How far apart (s) the two ends of an input's window must be for its order to be open."""


class ReplayError(Exception):
    """The replay cannot be made (one line): no such agent, nothing of it in the record, input
    outside the record, or an agent that cannot be built outside its run."""


@dataclass
class ReplayResult:
    """A replay's outcome: ``inputs`` fed, ``compared`` communicates of the run compared,
    ``differences`` in the order found, ``copies`` (recorded, replayed) not compared,
    ``failure`` what the agent raised if it stopped with an error (the replay stops there),
    ``missing`` what of the agent's communicates the record lacks (None: nothing; then the
    replay is made but cannot reproduce the run: :attr:`AgentRecord.missing`),
    ``counters`` of trouble the replayed agent counted (and ``run_counters``, the agent's
    counters when the run ended, None when the run folder has none), ``notes`` on the record and
    on the order taken, ``undecided`` the order of the run the replay cannot decide (None: none;
    its differences are then those of one order, not findings), and the wall time (s) the replay
    took in all and to build the agent."""

    agent: str
    run_dir: Path
    inputs: int = 0
    compared: int = 0
    differences: list[Difference] = field(default_factory=list)
    copies: tuple[int, int] = (0, 0)
    failure: str | None = None
    missing: str | None = None
    counters: dict[str, int] = field(default_factory=dict)
    run_counters: dict[str, int] | None = None
    notes: list[str] = field(default_factory=list)
    undecided: str | None = None
    seconds: float = 0.0
    build_seconds: float = 0.0

    @property
    def equal(self) -> bool:
        """The agent sent what it sent in the run, did not fail, and nothing of it is missing
        from the record."""
        return not self.differences and self.failure is None and self.missing is None


class _Failed(Exception):
    """The agent failed in the replay in a way of its own (its message says how)."""


class _Transport(MemoryTransport):
    """The replayed agent's handle on the bus: it offers the replay's sources and notes the
    key expressions the agent subscribes to."""

    def __init__(self, bus: MemoryBus, sources: ReplaySources) -> None:
        super().__init__(bus)
        self.sources = sources
        self.subscribed: list[str] = []

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        self.subscribed.append(key_expr)
        super().subscribe(key_expr, callback)


_Token = tuple[str | None, str]
"""(conversation-id, reply-with) of a communicate the agent sent in the run."""


def _answered(comm: Communicate) -> _Token | None:
    """The (conversation-id, in-reply-to) ``comm`` answers, None when it answers nothing."""
    return None if comm.in_reply_to is None else (comm.conversation_id, comm.in_reply_to)


def _before(output: Recorded, item: Recorded) -> bool:
    """Whether the agent's ``output`` was sent before input ``item`` (its sender's timestamps),
    neither a copy of an earlier one nor an answer to ``item``."""
    answers = output.comm.in_reply_to is not None and (
        output.comm.conversation_id,
        output.comm.in_reply_to,
    ) == (item.comm.conversation_id, item.comm.reply_with)
    return output.sent < item.sent and not output.copy and not answers


def _sent_by(items: list[Recorded]) -> list[float]:
    """The latest send time (POSIX s) of ``items`` up to each, copies left out (-inf before the
    first that is none): non-decreasing."""
    out, latest = [], -math.inf
    for item in items:
        if not item.copy:
            latest = max(latest, item.sent)
        out.append(latest)
    return out


def _in_time(
    inputs: list[Recorded], moved: frozenset[int], at: Callable[[Recorded], float]
) -> list[Recorded]:
    """``inputs`` in the order they are fed: as given, but each of ``moved`` (``seq``) where its
    time (``at``) puts it among the others (before the first fed later)."""
    out = [item for item in inputs if item.seq not in moved]
    for item in (item for item in inputs if item.seq in moved):
        t = at(item)
        out.insert(next((n for n, other in enumerate(out) if at(other) > t), len(out)), item)
    return out


class _Replay:
    """One replay under way (see the module docstring); ``causal`` False feeds the inputs as
    they come in the record, at the times the recorder saw them, none waiting for the agent;
    ``arrival`` names (``seq``) inputs taken when the recorder saw them instead of when they
    reached the agent (the other end of their window)."""

    def __init__(
        self,
        record: AgentRecord,
        agent: Agent,
        sources: ReplaySources,
        transport: _Transport,
        causal: bool = True,
        changes: list[Change] | None = None,
        arrival: frozenset[int] = frozenset(),
    ) -> None:
        self.record, self.agent, self.sources, self.transport = record, agent, sources, transport
        self.arrival = arrival if causal else frozenset(item.seq for item in record.inputs)
        self.inputs = _in_time(record.inputs, arrival if causal else frozenset(), self.at)
        """The inputs in the order they are fed."""
        self.first_at: float | None = None
        """The replayed clock (POSIX s) when the first difference was found."""
        self.changes = deque(changes or [])
        """The peers' tokens that appear or go away during the replay, in time order."""
        self.asked: set[_Token] = _asked(record) if causal else set()
        """The tokens of the agent's recorded communicates an input may answer."""
        self.causal = causal
        self.sent_by = {key: _sent_by(items) for key, items in record.outputs.items()}
        """Per key of the agent's: by each of its communicates on it, the latest send time of
        those up to it (copies left out), for a bisection."""
        self.after: dict[int, tuple[tuple[str, int], ...]] = {}
        """Per input (its ``seq``): what of the agent's it comes after (:meth:`_after`)."""
        self.replayed: set[_Token] = set()
        """The tokens of the recorded communicates the replayed agent has sent the like of."""
        self.held: list[Recorded] = []
        """Inputs waiting for the agent to send what came before them (:meth:`waits`), in input
        order."""
        self.ids = IdMap()
        self.differences: list[Difference] = []
        self.taken: dict[str, int] = defaultdict(int)  # per key: recorded outputs met so far
        self.seen: set[bytes] = set()
        self.compared = 0
        self.replayed_copies = 0
        transport.bus.subscribe(f"{keys.FIPA_PREFIX}*/{agent.name}/*", self._sent)

    def at(self, item: Recorded) -> float:
        """When input ``item`` is fed (POSIX s): when it reached the agent, or when the recorder
        saw it (``arrival``)."""
        return item.t if item.seq in self.arrival else item.came

    def run(self) -> None:
        wake = self.agent.engine.drive()
        self._check_inputs()
        for item in self.inputs:
            at = self.at(item)
            wake = self._peers_until(at, wake)
            wake = self._until(at, wake)
            if self.waits(item):
                self.held.append(item)
                continue
            self.sources.set(at)
            self._put(item)
            wake = self._drive()
        self._until(self.record.end, self._peers_until(self.record.end, wake))
        if self.held:  # inputs after what the replayed agent never sent
            for item in self.held:
                self._put(item)
            self.held.clear()
            self.agent.engine.drive()
        self.agent.engine.stop()
        self.agent.engine.drive()
        self._unsent()

    def waits(self, item: Recorded) -> bool:
        """Whether input ``item`` still waits for the replayed agent to send something it sent
        before ``item`` came in the run (module docstring); never when the replay is not causal."""
        token = _answered(item.comm)
        if token in self.asked and token not in self.replayed:
            return True
        return any(self.taken[key] <= i for key, i in self._after(item))

    def _after(self, item: Recorded) -> tuple[tuple[str, int], ...]:
        """Per key of the agent's to ``item``'s sender: the place of the last communicate on it
        that ``item`` must come after (sent before it, not a copy, not answering it); the agent
        has sent it once ``taken`` of that key is past it. Empty when the replay is not causal."""
        known = self.after.get(item.seq)
        if known is not None:
            return known
        peer = keys.parse_fipa_key(item.key).sender
        found = []
        for key, items in self.record.outputs.items() if self.causal else ():
            if keys.parse_fipa_key(key).receiver != peer:
                continue
            # the last place all before which were sent before item, then back past copies
            # and an answer to item
            last = bisect_left(self.sent_by[key], item.sent) - 1
            while last >= 0 and not _before(items[last], item):
                last -= 1
            if last >= 0:
                found.append((key, last))
        self.after[item.seq] = tuple(found)
        return self.after[item.seq]

    def _put(self, item: Recorded) -> None:
        """Put input ``item`` on the bus, with the replayed identifiers."""
        self.transport.bus.publish(item.key, encode(self._fed(item.comm)))

    def _drive(self) -> float | None:
        """Let the agent take its steps due now, each held input put in as soon as the agent has
        sent what came before it; the time it next waits for (None: none)."""
        wake = self.agent.engine.drive()
        while ready := [item for item in self.held if not self.waits(item)]:
            self.held = [item for item in self.held if item not in ready]
            for item in ready:
                self._put(item)
            wake = self.agent.engine.drive()
        return wake

    def _peers_until(self, t: float, wake: float | None) -> float | None:
        """Put on the bus, or take off it, each peer's token that changed up to ``t`` (POSIX s),
        at its time, the agent going on at each time it waits for before."""
        while self.changes and self.changes[0].t <= t:
            change = self.changes.popleft()
            wake = self._until(change.t, wake)
            self.sources.set(change.t)
            key = keys.alive_key(change.name)
            (self.transport.bus.announce if change.alive else self.transport.bus.withdraw)(key)
            wake = self._drive()
        return wake

    def _until(self, t: float, wake: float | None) -> float | None:
        """Let the agent go on at each time it waits for up to ``t`` (POSIX s)."""
        steps = 0
        while wake is not None and wake <= t:
            self.sources.set(max(wake, math.nextafter(self.sources.now, math.inf)))
            wake = self._drive()
            steps += 1
            if steps > MAX_STEPS:
                raise _Failed(f"{self.agent.name} took {MAX_STEPS} steps without input, never waiting")
        return wake

    def _check_inputs(self) -> None:
        # the simulation's time is not replayed: the agent's clock runs at the replayed clock's pace
        ours = {keys.inbox_key(self.agent.name), keys.COUNTERS_ASK, keys.SIM_CLOCK}
        other = [k for k in self.transport.subscribed if k not in ours]
        if other:
            raise ReplayError(
                f"{self.agent.name} takes input the traffic record does not hold ({', '.join(other)}): "
                "only an agent whose input is communicates can be replayed"
            )

    def _fed(self, comm: Communicate) -> Communicate:
        """``comm`` with the replayed identifiers of the conversations and replies it refers to;
        its own identifiers paired with themselves."""
        changes = {}
        for name in ("conversation_id", "reply_with", "in_reply_to"):
            old = getattr(comm, name)
            if old is None:
                continue
            new = self.ids.replayed(old)
            self.ids.pair(old, new)
            if new != old:
                changes[name] = new
        return msgspec.structs.replace(comm, **changes) if changes else comm

    def _sent(self, key: str, payload: bytes) -> None:
        """A communicate the agent sent (the bus's callback, on the driver's thread)."""
        digest = wire_digest(key, payload)
        if digest in self.seen:
            self.replayed_copies += 1
            return
        self.seen.add(digest)
        self._compare(key, payload)
        if self.first_at is None and self.differences:
            self.first_at = self.sources.now

    def _compare(self, key: str, payload: bytes) -> None:
        """Compare a communicate the agent sent on ``key`` with the next one it sent there in the
        run, the differences into :attr:`differences`."""
        at = self.sources.now
        recorded = self._next_recorded(key)
        if recorded is not None and recorded.comm.reply_with is not None:
            self.replayed.add((recorded.comm.conversation_id, recorded.comm.reply_with))
        try:
            comm = decode(payload)
        except DecodeError as exc:
            seq, t, what = (recorded.seq, recorded.t, recorded.line) if recorded else (None, at, key)
            self.differences.append(
                Difference(seq, t - self.record.t0, what, "communicate", "sent", f"does not decode: {exc}")
            )
            return
        if recorded is None:
            what = f"{self.agent.name} → {keys.parse_fipa_key(key).receiver} {comm.performative.value}"
            protocol = f" ({comm.protocol})" if comm.protocol else ""
            t = at - self.record.t0
            self.differences.append(Difference(None, t, what + protocol, "communicate", "not sent", "sent"))
            return
        self.compared += 1
        self.differences += compare(recorded, comm, at, self.ids, self.record.t0)

    def _next_recorded(self, key: str) -> Recorded | None:
        sent = self.record.outputs.get(key, [])
        i = self.taken[key]
        while i < len(sent) and sent[i].copy:
            i += 1
        self.taken[key] = i + 1
        return sent[i] if i < len(sent) else None

    def _unsent(self) -> None:
        for key in self.record.outputs:
            while (item := self._next_recorded(key)) is not None:
                self.differences.append(
                    Difference(
                        item.seq, item.t - self.record.t0, item.line, "communicate", "sent", "not sent"
                    )
                )
        if self.first_at is None and self.differences:
            self.first_at = self.sources.now


def replay(run_dir: Path, agent: str, spec: SystemSpec | None = None, *, causal: bool = True) -> ReplayResult:
    """Replay ``agent`` of the run in ``run_dir`` (see the module docstring; ``causal`` False
    feeds the inputs in the order and at the times they reached the recorder, none waiting, and
    tries no other order). Raises FileNotFoundError for a folder that does not exist, and
    ReplayError (one line) when the replay cannot be made: an agent the specification does not
    name, a record that holds nothing of it, an agent that cannot be built here or takes input
    outside the record."""
    started = time.perf_counter()
    spec = spec or default_spec()
    try:
        cls = agent_class(spec, agent)
        record = agent_record(Path(run_dir), agent, causal)
    except (SpecError, ValueError) as exc:
        raise ReplayError(str(exc)) from None
    made = _Made(Path(run_dir), cls, spec, record, _peers(Path(run_dir), record, spec, causal), causal)
    result, first = made.once()
    if causal and first is not None and result.failure is None and result.missing is None:
        result = _other_orders(made, result, first)
    result.seconds = time.perf_counter() - started
    return result


@dataclass
class _Made:
    """What every replay of one agent of one run is made of: the run folder, the agent's class,
    the specification, the agent's record and the peers' tokens; ``causal`` as :func:`replay`'s."""

    run_dir: Path
    cls: type[Agent]
    spec: SystemSpec
    record: AgentRecord
    peers: Timeline
    causal: bool

    def once(
        self, arrival: frozenset[int] = frozenset(), early: int | None = None
    ) -> tuple[ReplayResult, float | None]:
        """One replay, ``arrival`` the inputs (``seq``) fed when the recorder saw them, ``early``
        the peers' token change (its place in :attr:`Timeline.changes`) taken at the early end
        of its window (:meth:`changes`); and the replayed clock (POSIX s) at its first
        difference (None: none)."""
        started = time.perf_counter()
        record, agent = self.record, self.record.agent
        result = ReplayResult(
            agent, self.run_dir, inputs=len(record.inputs), missing=record.missing, notes=list(record.notes)
        )
        if record.sessions > 1:
            result.notes.append(
                f"{agent} sent from {record.sessions} sessions (it was restarted): replayed as one"
            )
        sources = ReplaySources(record.start)
        bus = MemoryBus()
        for name in sorted(self.peers.initial):
            bus.announce(keys.alive_key(name))
        with _isolated():
            transport = _Transport(bus, sources)
            try:
                instance = self.cls(transport, self.spec)
            except Exception as exc:
                raise ReplayError(f"{agent} cannot be built outside its run: {exc}") from None
            result.build_seconds = time.perf_counter() - started
            run = _Replay(record, instance, sources, transport, self.causal, self.changes(early), arrival)
            try:
                _run(run, result)
            finally:
                close = getattr(instance, "close", None)
                if callable(close):
                    close()
        result.counters = {k: instance.counters[k] for k in TROUBLE if instance.counters[k]}
        result.run_counters = _run_counters(self.run_dir, agent)
        return result, run.first_at

    def changes(self, early: int | None) -> list[Change]:
        """The peers' token changes, the one at ``early`` (None: none) taken the record's
        lateness earlier (the agent may have seen a token up to that long before the recorder
        did: a token carries no timestamp), never before that peer's change before it."""
        changes = list(self.peers.changes)
        if early is None:
            return changes
        c = changes[early]
        before = [d.t for d in changes[:early] if d.name == c.name]
        changes[early] = Change(max(c.t - self.record.lateness, *before, self.record.start), c.name, c.alive)
        return sorted(changes, key=lambda d: d.t)


def _other_orders(made: _Made, base: ReplayResult, first: float) -> ReplayResult:
    """``base`` (a replay that differs, first at the replayed clock's ``first``, POSIX s) or, when
    an input whose time the record leaves open was fed at one end of its window before that, a
    replay with it at the other end that reproduces the run (noted), or ``base`` saying it cannot
    decide that input's order when the differences depend on it (module docstring)."""
    record = made.record
    open_ = [
        item
        for item in record.inputs
        if abs(item.t - item.came) > ORDER_TOLERANCE_S and min(item.t, item.came) <= first
    ]
    depends: Recorded | None = None
    for item in sorted(open_, key=lambda i: min(i.t, i.came), reverse=True)[:MAX_ORDERS]:
        other, _ = made.once(frozenset({item.seq}))
        if other.equal:
            other.notes.append(
                f"#{item.seq} {item.line} taken as reaching {record.agent} when the recorder saw it, "
                f"at {item.t - record.t0:.3f} s, not at {item.came - record.t0:.3f} s: the record "
                "allows both, and the run is reproduced in this order"
            )
            other.build_seconds = base.build_seconds
            return other
        if depends is None and _found(other) != _found(base):
            depends = item
    early = _token_order(made, base, first)
    if early is not None:
        return early
    if depends is not None:
        base.undecided = (
            f"whether #{depends.seq} {depends.line} reached {record.agent} at "
            f"{depends.came - record.t0:.3f} s (sent then, by its path) or at "
            f"{depends.t - record.t0:.3f} s (when the recorder saw it): the replay differs either way"
        )
    return base


def _token_order(made: _Made, base: ReplayResult, first: float) -> ReplayResult | None:
    """A replay that reproduces the run with one peer's token that appeared around ``first``
    (POSIX s, the first difference of ``base``) taken the record's lateness earlier (noted), or
    None (module docstring)."""
    record = made.record
    appeared = [i for i, c in enumerate(made.peers.changes) if c.alive and c.t - record.lateness <= first]
    for i in reversed(appeared[-MAX_ORDERS:]):
        other, _ = made.once(early=i)
        if other.equal:
            c = made.peers.changes[i]
            other.notes.append(
                f"{c.name}'s token taken as seen by {record.agent} up to {record.lateness * 1000:.1f} ms "
                f"before {c.t - record.t0:.3f} s: the record allows it, and the run is reproduced so"
            )
            other.build_seconds = base.build_seconds
            return other
    return None


def _found(result: ReplayResult) -> list[tuple[int | None, str]]:
    """What ``result`` found, to tell two replays' findings apart."""
    return [(d.seq, d.field) for d in result.differences] + [(None, result.failure or "")]


def peers(run_dir: Path, agent: str, spec: SystemSpec | None = None) -> Timeline:
    """The peers' tokens the replay of ``agent`` of the run in ``run_dir`` sees, and when
    (:func:`_peers`). Raises as :func:`agent_record` does."""
    return _peers(Path(run_dir), agent_record(Path(run_dir), agent), spec or default_spec())


def _peers(run_dir: Path, record: AgentRecord, spec: SystemSpec, causal: bool = True) -> Timeline:
    """The peers' tokens the replay of ``record``'s agent sees (services/replay/presence.py):
    each change as the agent saw it (the recorder's time less the path from the token's owner
    to the recorder, more the path to the agent), an appearance no later than the first of the
    agent's communicates to the owner that it may have caused; ``causal`` False: each when the
    recorder saw it."""
    names = [a.name for a in spec.agents]
    if not causal:
        return timeline(read_presence(run_dir), record.agent, record.start, names)
    sent: dict[str, list[float]] = defaultdict(list)
    for key, items in record.outputs.items():
        sent[keys.parse_fipa_key(key).receiver] += [i.sent for i in items]
    return timeline(
        read_presence(run_dir),
        record.agent,
        record.start,
        names,
        paths=record.paths,
        sent={name: sorted(times) for name, times in sent.items()},
        came=sorted(item.came for item in record.inputs),
        window=record.lateness,
    )


def _run(run: _Replay, result: ReplayResult) -> None:
    """Make the replay, and fill ``result`` with what it found, also when the agent fails."""
    run.agent.engine.bind()
    try:
        run.run()
    except ReplayError:
        raise
    except _Failed as exc:
        result.failure = f"{exc} (at {run.sources.now - run.record.t0:.3f} s)"
    except Exception as exc:  # the agent stopped: what it raised is the finding
        t = run.sources.now - run.record.t0
        result.failure = f"{run.agent.name} raised at {t:.3f} s: {type(exc).__name__}: {exc}"
    result.compared = run.compared
    result.differences = run.differences
    recorded_copies = sum(item.copy for items in run.record.outputs.values() for item in items)
    result.copies = (recorded_copies, run.replayed_copies)


def _run_counters(run_dir: Path, agent: str) -> dict[str, int] | None:
    """``agent``'s counters in the run folder's counters.json (None: none there)."""
    try:
        report = read_counters(run_dir).get(agent)
    except (OSError, msgspec.DecodeError, msgspec.ValidationError):
        return None
    return report.counters if report is not None else None


@contextmanager
def _isolated() -> Iterator[None]:
    """The process's environment without the :data:`UNSET` settings and with :data:`KEPT` in
    a temporary folder (removed after), restored after."""
    names = [Settings.env_name(f) for f in (*UNSET, *KEPT)]
    before = {n: os.environ.pop(n) for n in names if n in os.environ}
    try:
        with tempfile.TemporaryDirectory(prefix="roco-replay-") as folder:
            for f in KEPT:
                os.environ[Settings.env_name(f)] = str(Path(folder) / f)
            yield
    finally:
        for n in names:
            os.environ.pop(n, None)
        os.environ.update(before)


def render(result: ReplayResult, most: int = 50) -> str:
    """The order the replay cannot decide (then the differences are those of the order taken),
    the differences one per line (at most ``most``, then how many more), what the agent
    raised, the notes, and a last line saying what was replayed and whether it was
    reproduced."""
    lines = [] if result.undecided is None else [f"cannot decide {result.undecided}; in the order taken:"]
    lines += [d.line() for d in result.differences[:most]]
    if len(result.differences) > most:
        lines.append(f"… and {len(result.differences) - most} more")
    if result.failure is not None:
        lines.append(result.failure)
    lines += [f"note: {n}" for n in result.notes]
    if result.counters:
        ran = result.run_counters
        counted = ", ".join(
            f"{k} {v}" + (f" ({ran.get(k, 0)} in the run)" if ran is not None else "")
            for k, v in result.counters.items()
        )
        lines.append(f"the replayed {result.agent} counted {counted}; --log prints its log")
    lines.append(_summary(result))
    return "\n".join(lines)


def one_line(result: ReplayResult) -> str:
    """The replay of one agent in one line: ``a_pl: reproduced, 32 inputs, 32 outputs``,
    ``a_pl: cannot reproduce: 2 inputs missing from the record (…)`` when the record lacks
    some of the agent's communicates (whatever the replay then differs in), ``a_ta: cannot
    decide whether #16 … reached a_ta at …`` when the differences depend on an order the record
    leaves open, or ``a_pl: 3 differences: <the first>`` (or what the agent raised)."""
    if result.missing is not None:
        return f"{result.agent}: cannot reproduce: {result.missing}"
    if result.undecided is not None:
        return f"{result.agent}: cannot decide {result.undecided}"
    if result.equal:
        return f"{result.agent}: reproduced, {result.inputs} inputs, {result.compared} outputs"
    found = len(result.differences)
    first = result.differences[0].line() if result.differences else result.failure
    failed = ", then it failed" if result.failure is not None and result.differences else ""
    return f"{result.agent}: {found} difference{'' if found == 1 else 's'}{failed}: {first}"


def _summary(result: ReplayResult) -> str:
    recorded_copies, replayed_copies = result.copies
    copies = ""
    if recorded_copies or replayed_copies:
        copies = f"; copies not compared: {recorded_copies} recorded, {replayed_copies} replayed"
    verdict = "reproduced" if result.equal else f"{len(result.differences)} difference(s)"
    if result.failure is not None:
        verdict += ", then it failed"
    if result.undecided is not None:
        verdict = f"cannot decide the order of the run ({verdict} in the order taken)"
    if result.missing is not None:
        verdict = f"cannot reproduce: {result.missing} ({verdict})"
    return (
        f"roco: {result.agent} replayed from {result.run_dir}: {result.inputs} communicates in, "
        f"{result.compared} compared{copies}; {verdict} "
        f"in {result.seconds:.2f} s ({result.build_seconds:.2f} s to build {result.agent})"
    )


def _asked(record: AgentRecord) -> set[_Token]:
    """The tokens (conversation-id, reply-with) of the agent's recorded communicates that an
    input may answer."""
    sent = (item.comm for items in record.outputs.values() for item in items)
    return {(c.conversation_id, c.reply_with) for c in sent if c.reply_with is not None}
