"""The engine that runs one agent (paper §3.2, eq. 2; §4): its buffers, its elementary actions
and the threads that run them; the manual: docs/agents.md ("How an agent runs").

An :class:`Engine` is built with its agent (services/runtime/agent.py ``Agent``), which holds
the author's declarations, hooks and handlers; the engine holds everything else:

- the transmission input buffer :attr:`Engine.x` (:class:`Received` communicates), the receptor
  input buffer :attr:`Engine.r` and the output buffer :attr:`Engine.y`, put on the transport
  after each step (services/runtime/emission.py ``Outbox``);
- the checks against the specification (paper §4 steps 3–4; FIPA SC00061, SC00026/27/35):
  what comes in passes services/runtime/admission.py ``Gate``, what is not taken is answered
  by services/runtime/rejections.py; what the agent sends passes
  services/runtime/send_checks.py (SpecViolation); nothing a peer sends stops the agent;
- the protocol state of every conversation (services/runtime/protocol_state.py), reply-by
  deadlines and retransmission (services/runtime/replies.py), at-most-once handling
  (services/runtime/dedup.py), the protocol roles (services/runtime/roles/);
- peer liveliness, readiness (:attr:`Engine.ready`, :attr:`Engine.on_ready`), persistence
  after every step (services/runtime/state_store.py), the FSM's clock
  (:attr:`Engine.fleet_clock`), the counters on request (``roco/counters/ask``);
- one thread at a time runs the elementary actions: the agent's own (:meth:`Engine.run`) or,
  while it is idle, the transport's receiving thread (:meth:`Engine._take_here`;
  ``RECEIVE_INLINE = False`` keeps every step on the agent's). A driver that owns the agent's
  time and input (``roco replay``) calls :meth:`Engine.drive` instead.

The elementary action (paper §3.2): compute the transition function, dispatch the output
buffer, increment i, acquire new inputs. It repeats until the behaviour's terminal or error
condition holds; then the FSM's initial conditions choose the next behaviour.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Generator
from typing import Any, NoReturn, Protocol

import msgspec

from services.runtime import fsm_record, keys
from services.runtime.admission import Admission, Gate
from services.runtime.behaviour import FSM
from services.runtime.clock import FleetClock, decode_sim_time
from services.runtime.dedup import Dedup
from services.runtime.emission import Outbox, Outgoing
from services.runtime.heap import give_back_freed_heap
from services.runtime.hooks import Hooks, load_hooks
from services.runtime.limits import MAX_OPEN_CONVERSATIONS_PER_PEER
from services.runtime.lookups import Lookups
from services.runtime.protocol_state import ProtocolStates
from services.runtime.rejections import Rejections
from services.runtime.replies import Pending, PendingReplies
from services.runtime.roles import Conversation, RoleDecl, Roles
from services.runtime.send_checks import SendChecks
from services.runtime.sources import SYSTEM, Sources
from services.runtime.state_store import NO_DATA, KeptConversations, StateFile
from services.runtime.transport import Transport
from services.runtime.values import Received, SpecViolation
from services.spec.model import Interface, SystemSpec, asked, default_spec, interface
from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.batch import BATCH_HEADS, unpack
from shared.settings import Settings

ALIVE = "\x00alive"
"""Input-queue key of a peer liveliness event (never a Zenoh key)."""
COUNTERS = "\x00counters"
"""Input-queue key of a request for the agent's counters (``roco/counters/ask``)."""
INLINE_OUTPUT_MAX = 32
"""Communicates a step taken in on a receiving thread may put from that thread; a step that
sends more (a stream) is dispatched by the agent's own thread (see :meth:`Engine._take_here`)."""
INLINE_GAP_S = 200e-6
"""On a transport that cannot tell whether more input waits (no ``more_waiting``): a
communicate that arrives within this time (s) of the one before it is handed to the agent's
thread, which takes what has arrived together in one step (a stream), instead of being taken in
on the receiving thread one step each (see :meth:`Engine._take_here`)."""
INLINE_BUDGET_S = 0.05
"""Longest a step may compute on a receiving thread (s of the thread's CPU time): an agent whose
step computed longer takes its input on its own thread from then on. CPU time, not wall time:
with 100 agent processes on 2 cores a 100 µs step waits tens of ms for a core at times, and a
wall-time budget turned inline receiving off for a third of them (docs/benchmarks.md, "Fewer
wake-ups per communicate")."""


class Author(Protocol):
    """What an :class:`Engine` asks of the agent it runs (services/runtime/agent.py ``Agent``):
    its declarations, its hooks and its note."""

    note: Any

    @property
    def name(self) -> str: ...

    @property
    def ROLES(self) -> tuple[RoleDecl, ...] | None: ...

    @property
    def NOTE(self) -> type[msgspec.Struct] | None: ...

    @property
    def period(self) -> float: ...

    @property
    def RECEIVE_INLINE(self) -> bool: ...

    def build_fsm(self) -> FSM: ...

    def setup(self) -> None: ...

    def peer_changed(self, peer: str, alive: bool) -> None: ...

    def persist(self) -> None: ...

    def on_restored(self, conversation: Conversation) -> None: ...


class Engine:
    """Runs ``agent`` (its FSM, hooks and handlers) on ``transport`` against ``spec`` (None: the
    default specification). Built by ``Agent.__init__``; :meth:`start` ends the building once
    the agent's own attributes exist. Raises SpecError when the agent's name is not in the
    specification, RoleMismatch when its roles differ from its interface."""

    fsm: FSM
    """The agent's FSM of behaviours (its ``build_fsm``), built by :meth:`start`."""

    def __init__(self, agent: Author, transport: Transport, spec: SystemSpec | None = None) -> None:
        self.agent = agent
        self.name: str = agent.name
        self.spec = spec or default_spec()
        self.transport = transport
        self.sources: Sources = getattr(transport, "sources", None) or SYSTEM
        """The agent's clocks, random bytes and fresh identifiers (services/runtime/sources.py):
        the transport's ``sources`` if it offers them (a replay's), else the system's."""
        self.hooks: Hooks | None = load_hooks()
        """A viewer's hooks, given to this agent (services/runtime/hooks.py); None: no viewer."""
        self.aid = AgentIdentifier(self.name)
        self.interface: Interface = interface(self.spec, self.name)
        self.lookups = Lookups(self.spec, self.interface, self.name)
        """The specification's answers per peer, channel and kind, kept (services/runtime/lookups.py)."""
        self.log = logging.getLogger(self.name)
        self.x: deque[Received] = deque()
        self.r: deque[Any] = deque()
        self.y: list[tuple[str, bytes]] = []
        """The output buffer: (key, payload) put on the transport after the step."""
        self.i = 0
        self.state = ""
        """The behaviour the FSM is in (its state's name)."""
        self.counters: Counter[str] = Counter()
        self.pending_replies = PendingReplies()
        """The replies this agent awaits (reply-by deadlines, retransmissions)."""
        self.protocol_states = ProtocolStates()
        self.dedup = Dedup()
        self.peers: set[str] = set()
        """Agents whose liveliness token is present (kept up to date on the agent's thread)."""
        self.asks: tuple[str, ...] = asked(self.spec, self.name)
        """The agents this one asks (services/spec/model.py ``asked``): it is :attr:`ready` once
        it has seen each of them."""
        self.ready = False
        """Set once, on the agent's thread: its ``setup`` has run, the liveliness token is
        declared and every agent of :attr:`asks` has been seen. It stays set when one of them
        disappears later (that one's own readiness says so)."""
        self.on_ready: Callable[[str], None] | None = None
        """Called once when the agent becomes :attr:`ready`, with one line saying so (the process
        writes it to its ready file, services/runtime/main.py); None: nothing is called."""
        self._set_up = False  # setup() has run and the liveliness token is declared
        self.max_open_per_peer = MAX_OPEN_CONVERSATIONS_PER_PEER
        """Open conversations a peer may have with this agent before a new one is refused."""
        self.checks = SendChecks(
            self.name, self.spec, self.lookups, self.protocol_states, self.counters, self.log
        )
        """The interface's checks of what the agent sends (services/runtime/send_checks.py)."""
        declared = agent.ROLES
        self.roles = Roles(self, agent, declared or (), check=declared is not None)
        """The agent's protocol roles and their open conversations (services/runtime/roles/)."""
        self.rejections = Rejections(self)
        """The answers to what is not taken in (services/runtime/rejections.py)."""
        self._outbox = Outbox(
            self,
            self.name,
            self.aid,
            self.protocol_states,
            self.dedup,
            self.pending_replies,
            self.checks.outgoings,
            self.y,
            self.counters,
        )
        self._gate = Gate(
            self,
            self.lookups,
            self.dedup,
            self.protocol_states,
            self.pending_replies,
            self.x,
            self.counters,
            Received,
            frozenset(("r", ALIVE, COUNTERS)),
        )
        self._y_taken = 0
        """How much of ``y`` taking inputs in put there (answers a failing behaviour keeps)."""
        self.batch_puts = True
        """Communicates that one step sends in a row to one receiver go in one put, a batch
        (shared/fipa_codec/batch.py); False: one put each (the benchmark compares the two)."""
        self._inbox: deque[tuple[str, Any]] = deque()
        """Inputs waiting for a step: (key, payload) of a communicate, or a runtime event."""
        self._arrived_lock = threading.RLock()  # an RLock: stop() may run in a signal handler
        self._arrived = threading.Condition(self._arrived_lock)
        self._sleepers = 0
        """Threads waiting on ``_arrived`` (:meth:`_sleep`): an input put while none waits
        notifies nobody (the notification is a Python call of ``threading``)."""
        self._turn = threading.Lock()
        """Held by whichever thread runs the agent's elementary actions (:meth:`run`)."""
        self._actions: Generator[float, None, None] | None = None
        self._wake_at = 0.0  # sources.monotonic() at which the suspended actions want to go on
        self._ended = False
        self._failure: BaseException | None = None
        self._here = False  # the actions run on a receiving thread (_take_here)
        self._last_arrival = 0.0  # time.perf_counter() of the last communicate's arrival
        self._declared = getattr(transport, "declared", None)
        """The transport's ``declared(key)`` (services/runtime/transport.py ``Transport``), if any."""
        self._more_waiting: Callable[[], bool] | None = getattr(transport, "more_waiting", None)
        """The transport's ``more_waiting()`` (a burst is arriving), if any."""
        self._inline = (
            agent.RECEIVE_INLINE
            and bool(getattr(transport, "inline_receive", False))
            and Settings.from_env(only=("receive",)).receive != "agent-thread"
        )
        self._stop = threading.Event()
        self.fleet_clock = FleetClock(self.sources.monotonic)
        """The clock the FSM's periodic behaviours run on (services/runtime/clock.py): the
        simulation's pace once ag_ex's ``roco/sim/clock`` is heard (:meth:`bind`), the wall
        clock's before and in real time."""
        self.fsm_record = fsm_record.for_agent(self.name)
        """Where the agent records its FSM's transitions and its time-outs
        (services/runtime/fsm_record.py); None: neither a run folder nor a tap folder is set."""
        keeps = self.roles.keeps or agent.NOTE is not None
        self._kept: StateFile[KeptConversations] | None = (
            StateFile.for_agent(self.name, KeptConversations) if keeps else None
        )
        """Where the runtime keeps the conversations of the roles declared with ``keep`` and the
        agent's ``note`` (services/runtime/state_store.py); None: the agent keeps neither."""
        self._kept_last: KeptConversations | None = None  # what keep() last wrote
        self.persist: Callable[[], None] = agent.persist
        """Called after every step (the agent's ``persist``; ``Agent`` sets :meth:`keep` itself
        when its class does not define ``persist`` again: no call into the agent then)."""

    def start(self) -> None:
        """End the building, once the agent's attributes exist (``Agent.__init__``): build its
        FSM (``build_fsm``), put its periodic behaviours on :attr:`fleet_clock`, and take back
        what was kept before a restart (``on_restored`` per conversation)."""
        fsm = self.fsm = self.agent.build_fsm()
        for b in fsm.states.values():
            if b.timer is not None:  # a timer that asks for the wall clock, or gives its own, keeps it
                b.timer.bind(self.fleet_clock, self.sources.monotonic)
        self._take_back()

    # ---- sending (the agent's context calls these; services/runtime/roles/ too) ----------
    def send(
        self,
        to: str,
        performative: Performative,
        content: msgspec.Struct | None = None,
        *,
        protocol: str,
        conversation_id: str | None = None,
        reply_with: str | None = None,
        in_reply_to: str | None = None,
        reply_by_s: float | None = None,
        expect_reply: bool = False,
        retry_s: float | None = None,
    ) -> Communicate:
        """Put a communicate for ``to`` into the output buffer (sent after this step).

        ``content`` is a term of a content language (its language is set from its type).
        ``expect_reply`` (or ``reply_by_s``) registers the conversation so that replies are
        matched and, after ``reply_by_s`` seconds, a local failure ends it. ``retry_s``
        (s, > 0) retransmits the same bytes every ``retry_s`` until the first reply arrives
        (and at once when ``to`` reappears; ``RESEND_ON_RETURN``: only then); use it
        where a repeated communicate is harmless to the receiver (its runtime drops
        byte-identical copies).
        Raises SpecViolation when no channel joins the agents or the interface forbids it;
        ValueError for a ``retry_s`` that is not positive.
        """
        return self._outbox.send(
            to,
            performative,
            content,
            protocol,
            conversation_id,
            reply_with,
            in_reply_to,
            reply_by_s,
            expect_reply,
            retry_s,
        )

    def reply(
        self,
        to: Received,
        performative: Performative,
        content: msgspec.Struct | None = None,
        *,
        reply_with: str | None = None,
        reply_by_s: float | None = None,
        expect_reply: bool = False,
        retry_s: float | None = None,
    ) -> Communicate:
        """Reply within ``to``'s conversation: same protocol and conversation-id,
        in-reply-to = its reply-with (other arguments and errors as :meth:`send`)."""
        msg = to.msg
        return self._outbox.send(
            to.sender,
            performative,
            content,
            msg.protocol or "",
            msg.conversation_id,
            reply_with,
            msg.reply_with,
            reply_by_s,
            expect_reply,
            retry_s,
        )

    def fail(self, to: Received, performative: Performative, reason: str) -> None:
        """Answer ``to`` with ``failure`` or ``refuse`` carrying ``reason`` as UTF-8 text
        (services/runtime/rejections.py ``Rejections.fail``; raises SpecViolation)."""
        self.rejections.fail(to, performative, reason)

    def not_understood(
        self, sender: str, channel: str, why: str, about: Communicate | None, reason: str = "unhandled"
    ) -> None:
        """Answer ``about`` from ``sender`` with not-understood for ``why``, counted under
        ``rejected.<reason>`` (services/runtime/rejections.py ``Rejections.not_understood``)."""
        self.rejections.not_understood(sender, channel, why, about, reason)

    def emit(self, key: str, payload: bytes) -> None:
        """Put a payload for one of the agent's effectors (a non-FIPA key), or an already
        encoded communicate sent again as it was, into the output buffer."""
        self.y.append((key, payload))

    def outgoing(
        self, to: str, performative: Performative, protocol: str, content: msgspec.Struct | None
    ) -> Outgoing:
        """The interface's checks of a route, kept (services/runtime/send_checks.py)."""
        return self.checks.outgoing(to, performative, protocol, content)

    def conversation_stepped(
        self, peer: str, conversation_id: str, performative: Performative, outcome: str
    ) -> None:
        """A communicate that crossed another on the wire: counted."""
        self.checks.stepped(outcome)

    def send_violation(self, conversation_id: str | None, text: str) -> NoReturn:
        """Count, log and raise SpecViolation (services/runtime/send_checks.py)."""
        self.checks.violation(conversation_id, text)

    def counters_report(self) -> bytes:
        """The agent's counters as JSON: ``{"agent": name, "time": POSIX s, "session": Zenoh
        session id or "", "counters": {name: count}}`` (what ``roco/counters/report/<agent>``
        carries; services/runtime/counters.py)."""
        session = getattr(self.transport, "session_id", "")
        return msgspec.json.encode(
            {
                "agent": self.name,
                "time": self.sources.time(),
                "session": session,
                "counters": dict(self.counters),
            }
        )

    def restore_conversation(
        self,
        peer: str,
        conversation_id: str,
        protocol: str,
        history: list[tuple[Performative, bool]],
        opening_reply_with: str | None = None,
    ) -> None:
        """Re-enter the protocol state of a conversation kept across a restart: replay its
        ``history`` of (performative, sent by this agent) in order; an ``inform`` counts as a
        non-terminal report. ``opening_reply_with``: the reply-with of the communicate that
        opened it, so that a retransmission of it is recognised (protocol_state ``judge``).
        Raises SpecViolation when the history is not a path of the protocol."""
        for performative, sent in history:
            why = self.checks.follow(peer, conversation_id, protocol, performative, sent, False)
            if why is not None:
                self.protocol_states.rollback()
                raise SpecViolation(f"cannot restore conversation {conversation_id} with {peer}: {why}")
        tracker = self.protocol_states.get(peer, conversation_id)
        if tracker is not None and opening_reply_with:
            tracker.opening_reply_with = opening_reply_with
        self.protocol_states.commit()

    # ---- persistence ---------------------------------------------------------------------
    def keep(self) -> None:
        """Write the open conversations of the roles declared with ``keep`` and the agent's
        ``note`` when they changed since the last write (``Agent.persist``'s default). Raises
        OSError when the state folder cannot be written."""
        if self._kept is None:
            return
        kept = self.roles.kept()
        note = self.agent.note
        if note is not None:
            kept.note = msgspec.Raw(msgspec.json.encode(note))
        if kept != self._kept_last:  # compared field by field: the openings are the same bytes
            self._kept.save(kept)
            self._kept_last = kept

    def _take_back(self) -> None:
        """Take back the conversations (and the note) kept before a restart."""
        kept = self._kept.load() if self._kept is not None else None
        if kept is None:
            return
        agent = self.agent
        note_type = agent.NOTE
        if note_type is not None and bytes(kept.note) != bytes(NO_DATA):
            try:
                agent.note = msgspec.json.decode(kept.note, type=note_type)
            except (msgspec.DecodeError, msgspec.ValidationError) as exc:
                self.log.warning("the kept note does not decode (%s): a new one is begun", exc)
        n = 0
        for conv in self.roles.take_back(kept):
            try:
                agent.on_restored(conv)
            except (TypeError, ValueError) as exc:
                self.log.warning(
                    "a kept %s conversation cannot be taken back (%s): dropped", conv.decl.protocol, exc
                )
                conv.forget()
                continue
            n += 1
        if n:
            where = self._kept.path if self._kept else ""
            self.log.info("took back %d kept conversation(s) from %s", n, where)

    # ---- receiving -----------------------------------------------------------------------
    def bind(self) -> None:
        """Subscribe the input buffer and watch the peers' liveliness; hear the simulation's
        time (:attr:`fleet_clock`) unless the fleet runs in real time (``ROCO_REALTIME``). The
        agent's own liveliness token is declared by :meth:`run`, after its ``setup``: a peer
        (or a person) that sees it finds every subscription of the agent in place."""
        self.transport.subscribe(keys.inbox_key(self.name), self._on_payload)
        self.transport.subscribe(keys.COUNTERS_ASK, self._on_counters_ask)
        self.transport.watch(keys.ALIVE_ALL, self._on_alive)
        if not Settings.from_env(only=("realtime",)).realtime:
            self.transport.subscribe(keys.SIM_CLOCK, self._on_sim_clock)

    def post(self, event: Any) -> None:
        """Put a receptor event into the agent (thread-safe; wakes a waiting behaviour)."""
        self._put_input(("r", event))

    def _put_input(self, item: tuple[str, Any]) -> None:
        """Hand an input to the agent's thread (any thread; wakes it)."""
        with self._arrived_lock:
            self._inbox.append(item)
            if self._sleepers:
                self._arrived.notify()

    def _sleep(self, timeout: float) -> None:
        """Wait on ``_arrived`` (its lock held) up to ``timeout`` s for an input, counted in
        ``_sleepers`` so that an input put meanwhile wakes this thread."""
        self._sleepers += 1
        try:
            self._arrived.wait(timeout)
        finally:
            self._sleepers -= 1

    def _on_payload(self, key: str, payload: bytes) -> None:  # the transport's thread
        if payload and payload[0] in BATCH_HEADS:  # a batch (batch.py is_batch, without its call)
            with self._arrived_lock:
                self._inbox.extend([(key, part) for part in unpack(payload)])
                if self._sleepers:
                    self._arrived.notify()
            return
        if not (self._inline and not self._in_burst() and self._take_here((key, payload))):
            with self._arrived_lock:  # as _put_input, without its call: once per communicate
                self._inbox.append((key, payload))
                if self._sleepers:
                    self._arrived.notify()

    def _in_burst(self) -> bool:
        """Whether the communicate being received arrived in a burst, to be taken in with the
        others by the agent's thread: another one waits behind it (the transport's
        ``more_waiting``), else (a transport that cannot tell) it came within
        :data:`INLINE_GAP_S` of the one before."""
        if self._more_waiting is not None:
            return self._more_waiting()
        now = time.perf_counter()
        apart, self._last_arrival = now - self._last_arrival, now
        return apart <= INLINE_GAP_S

    def _on_sim_clock(self, key: str, payload: bytes) -> None:
        with contextlib.suppress(ValueError):  # not a simulation time: the clock runs on as it did
            self.fleet_clock.mark(decode_sim_time(payload))  # thread-safe: no input to take in

    def _on_counters_ask(self, key: str, payload: bytes) -> None:
        self._put_input((COUNTERS, None))  # Zenoh thread: enqueue only

    def _on_alive(self, key: str, alive: bool) -> None:
        name = keys.alive_agent(key)
        if name is not None:  # a token that carries no agent name is none of an agent
            self._put_input((ALIVE, (name, alive)))  # Zenoh thread: enqueue only

    def _take_here(self, item: tuple[str, Any]) -> bool:
        """Take ``item`` in on the calling (receiving) thread and run the agent's elementary
        actions on it until they block for input again, when the agent is idle: no thread runs
        them, none is about to (the turn is free) and no input waits before this one. Returns
        False, having done nothing, otherwise: the caller hands the item to the agent's thread.
        (A communicate that arrives in a burst is not offered here: what arrives together is
        taken in together, by the agent's thread; see :meth:`_in_burst`.)

        What runs here is what the agent's thread would run, under the same turn, so every
        check of the input is the same. A step whose output buffer holds more than
        :data:`INLINE_OUTPUT_MAX` communicates, or one on a key the transport has no publisher
        for yet, goes on on the agent's thread (a receiving thread never declares, and never
        puts a stream); a step that computed longer than :data:`INLINE_BUDGET_S` ends inline
        receiving for this agent."""
        if not self._turn.acquire(blocking=False):
            return False
        try:
            if self._inbox or self._actions is None or self._ended:
                return False
            waiting_until = self._wake_at
            self._inbox.append(item)
            self.counters["received_inline"] += 1
            self._here = True
            started, computed_from = time.perf_counter(), time.thread_time()
            try:
                self._resume()
            finally:
                self._here = False
            # the step's own CPU time, looked at only when its wall time is over the budget:
            # a thread that waited for a core (many processes on few cores) or for room in a
            # link did not compute that long
            if time.perf_counter() - started > INLINE_BUDGET_S:
                computed = time.thread_time() - computed_from
                if computed > INLINE_BUDGET_S:
                    self._inline = False
                    self.log.info(
                        "a step computed for %.0f ms on a receiving thread: input goes to the "
                        "agent's thread from now on",
                        computed * 1e3,
                    )
        finally:
            self._turn.release()
        if self._ended or self._wake_at < waiting_until:  # the agent's thread waits too long
            with self._arrived:
                self._arrived.notify()
        return True

    def _dispatch_here(self) -> bool:
        """The output buffer may be put from a receiving thread (see :meth:`_take_here`)."""
        if len(self.y) > INLINE_OUTPUT_MAX:
            return False
        declared = self._declared
        return declared is None or all(declared(key) for key, _ in self.y)

    # ---- acquiring inputs ----------------------------------------------------------------
    def _acquire_blocking(self, timeout: float) -> Generator[float, None, None]:
        """Acquire new inputs into x and r, blocking up to ``timeout`` (s) for the first: the
        elementary actions are suspended (yield the time to wait) until an input arrives or the
        time passes, then :meth:`acquire`."""
        deadline = self.pending_replies.next_deadline()
        if deadline is not None:
            timeout = max(0.0, min(timeout, deadline - self.sources.time()))
        if timeout > 0 and not self._inbox:
            yield timeout
        elif self._here:  # actions that go on without waiting go on on the agent's thread
            yield 0.0
        self.acquire()

    def acquire(self, timeout: float = 0.0) -> None:
        """Acquire the inputs that had arrived when it began into x and r (what arrives
        meanwhile waits for the next step: input arriving faster than the agent takes it in
        cannot keep its behaviours from running); retransmit what is due; end conversations
        whose reply-by deadline passed with a local failure. ``timeout`` (s) > 0 first waits
        that long at most for an input when none is there (an agent driven by hand, in tests
        and scripts: :meth:`run` suspends its actions instead)."""
        if timeout > 0 and not self._inbox:
            with self._arrived:
                if not self._inbox:
                    self._sleep(timeout)
        if self._inbox:
            self._gate.take_all(self._inbox, self.max_open_per_peer)
        now = self.sources.time()
        if self.roles.ticks:  # subscription attempts that are due (services/runtime/roles/subscriptions.py)
            self.roles.tick(now)
        self.protocol_states.commit()  # what arrived stays arrived; only sends are undone
        self._y_taken = len(self.y)  # so do the answers to it (not-understood, copies again)
        if now >= self.pending_replies.earliest:  # a deadline or a retransmission may be due
            self._overdue(now)

    def take(self, key: str, payload: Any) -> None:
        """Take one input in, as :meth:`acquire` does (tests and tools hand inputs over)."""
        self._gate.take_all(deque(((key, payload),)), self.max_open_per_peer)

    def _overdue(self, now: float) -> None:
        """Retransmit what is due at POSIX time ``now``; end the conversations whose reply-by
        deadline passed with a local failure (see :meth:`acquire`)."""
        for p in self.pending_replies.due(now):
            self.counters["retransmitted"] += 1
            self.log.info(
                "retransmitting %s to %s (conversation %s, #%d)",
                p.reply_with,
                p.peer,
                p.conversation_id,
                p.retransmissions,
            )
            self.y.append((p.key, p.payload))
        for p in self.pending_replies.expired(now):
            self.counters["deadline_failures"] += 1
            if self.fsm_record is not None:
                self._record_time_out(p)
            synthetic = Communicate(
                performative=Performative.FAILURE,
                sender=AgentIdentifier(p.peer),
                receiver=(self.aid,),
                content=b"reply-by deadline passed",
                encoding="utf-8",
                protocol=p.protocol,
                conversation_id=p.conversation_id,
                in_reply_to=p.reply_with,
            )
            self.x.append(Received.of(synthetic, None, "", local=True))

    def _record_time_out(self, p: Pending) -> None:
        """Record that ``p``'s reply-by deadline passed, with the conversation's protocol state."""
        assert self.fsm_record is not None
        tracker = self.protocol_states.get(p.peer, p.conversation_id) if p.conversation_id else None
        state = tracker.state if tracker is not None else None
        self.fsm_record.timed_out(p.peer, p.protocol, p.conversation_id, state)

    # ---- what Gate hands over (services/runtime/admission.py ``Host``) ---------------------
    def take_event(self, key: str, payload: Any) -> None:
        """Take in an input of the runtime's own: a command for ``r``, a peer's liveliness, a
        request for the counters."""
        if key == "r":
            self.r.append(payload)
        elif key == ALIVE:
            self._peer_event(*payload)
        else:
            self.y.append((keys.counters_key(self.name), self.counters_report()))

    def not_taken(self, found: Admission) -> None:
        """A communicate ``admit`` did not take: answered or dropped (services/runtime/rejections.py)."""
        self.rejections.not_taken(found)

    def take_raised(self, key: str) -> None:
        """Taking in the communicate on ``key`` raised: counted and logged; the agent goes on."""
        self.rejections.taking_raised(key)

    def _peer_event(self, peer: str, alive: bool) -> None:
        if peer == self.name:
            return
        if alive:
            self.peers.add(peer)
            n = self.pending_replies.retry_now(peer, self.sources.time())
            if n:
                self.log.info("%s appeared: %d unanswered communicate(s) to it sent again", peer, n)
            self._check_ready()
        else:
            self.peers.discard(peer)
            self.log.info("%s disappeared", peer)
        self.roles.peer_changed(peer, alive)  # the subscriptions kept with it
        self.agent.peer_changed(peer, alive)

    def _check_ready(self) -> None:
        """Become :attr:`ready` when set up with every agent of :attr:`asks` seen (once)."""
        if self.ready or not self._set_up or not self.peers.issuperset(self.asks):
            return
        self.ready = True
        seen = f"; {', '.join(self.asks)} seen" if self.asks else ""
        self.log.info("ready: roles set up%s", seen)
        if self.on_ready is not None:
            self.on_ready(f"{self.name} ready: roles set up{seen}")

    # ---- the loop -----------------------------------------------------------------------
    def dispatch(self) -> None:
        """Put the output buffer (communicates that one step sends in a row to one receiver in
        one batch, :attr:`batch_puts`); what it held is sent: its protocol states are kept
        (services/runtime/emission.py ``Outbox.dispatch``)."""
        self._outbox.dispatch(self.transport.publish, self.batch_puts)
        self._y_taken = 0

    def stop(self) -> None:
        """End :meth:`run` after the current step (any thread; also a signal handler)."""
        self._stop.set()
        self._put_input(("r", None))

    @property
    def stopping(self) -> bool:
        """:meth:`stop` was called (the elementary actions end after the current step)."""
        return self._stop.is_set()

    def run(self) -> None:
        """Run the FSM until :meth:`stop`. The elementary actions run on the calling thread,
        the agent's own, except while the agent is idle: then a communicate that arrives is
        taken in, and the actions run until they block again, on the thread it arrived on
        (:meth:`_take_here`). Either way one thread at a time runs them, holding the turn.
        Raises what a step raised outside a transition function (on either thread)."""
        with self._turn:
            self._actions = self._elementary_actions()
            self._resume()
            give_back_freed_heap()  # what start-up freed, once the first step has blocked
            while not self._ended:
                self._turn.release()
                try:
                    with self._arrived:
                        while not self._inbox and not self._ended:
                            left = self._wake_at - self.sources.monotonic()
                            if left <= 0:
                                break
                            self._sleep(left)
                finally:
                    self._turn.acquire()
                # a step taken in elsewhere meanwhile may have moved the time to go on
                if not self._ended and (self._inbox or self.sources.monotonic() >= self._wake_at):
                    self._resume()
        if self._failure is not None:
            raise self._failure

    def drive(self) -> float | None:
        """Run the elementary actions on the calling thread until they block for input: for a
        driver that owns the agent's time and input (``roco replay``, services/replay: the
        transport's ``sources`` and an in-memory bus), instead of :meth:`run`. The first call
        begins them (``setup``, the liveliness token); each later one goes on with what was
        put on the transport since, or with nothing once the time they waited for has come.
        Returns that time (``sources.monotonic()`` s); None once they have ended (after
        :meth:`stop`). Raises what a step raised outside a transition function."""
        with self._turn:
            if self._actions is None:
                self._actions = self._elementary_actions()
            if not self._ended:
                self._resume()
        return None if self._ended else self._wake_at

    def _resume(self) -> None:
        """Run the suspended elementary actions until they block for input (turn held)."""
        assert self._actions is not None
        try:
            timeout = next(self._actions)
        except StopIteration:
            self._ended = True
            return
        except BaseException as exc:
            self._ended = True
            if not self._here:
                raise
            self._failure = exc  # raised by run() on the agent's thread
            return
        self._wake_at = self.sources.monotonic() + timeout

    def _elementary_actions(self) -> Generator[float, None, None]:
        """The agent's elementary actions (paper §3.2), suspended (yielding the time, s, they
        wait for) wherever a behaviour blocks for input, or with 0 where a step taken in on a
        receiving thread must go on on the agent's own (:meth:`_dispatch_here`)."""
        agent, fsm = self.agent, self.fsm
        agent.setup()
        self.transport.announce(keys.alive_key(self.name))
        self._set_up = True
        self._check_ready()
        self.dispatch()
        state = fsm.initial
        if self.fsm_record is not None:
            self.fsm_record.declared(fsm, f"{type(agent).__module__}:{type(agent).__qualname__}")
            self.fsm_record.entered(state, "start")
        while not self._stop.is_set():
            self.state = state
            behaviour = fsm.states[state]
            self.log.debug("behaviour %s", behaviour.name)
            behaviour.on_enter()
            failed = False
            while not self._stop.is_set():
                try:
                    behaviour.transition()
                except Exception:
                    # a fault in one behaviour must not stop the agent: end the behaviour,
                    # drop what it was about to send, and go back to the initial state
                    self.log.exception("transition function of %s raised", behaviour.name)
                    self.counters["behaviour_errors"] += 1
                    del self.y[self._y_taken :]  # the answers taking inputs in gave stay
                    self.protocol_states.rollback()  # what was dropped was never sent
                    failed = True
                    break
                if self._here and not self._dispatch_here():
                    yield 0.0
                self.dispatch()
                self.persist()
                self.i += 1
                # a communication state blocks for new input only while it has nothing to end on
                # (a periodic one no longer than until its next period is due)
                done = behaviour.error() or behaviour.terminal()
                wait = agent.period if behaviour.waits and not done else 0.0
                if wait and behaviour.timer is not None:
                    wait = min(wait, behaviour.timer.wall_left())
                yield from self._acquire_blocking(wait)
                if done or behaviour.error() or behaviour.terminal():
                    break
            if self._stop.is_set():
                break
            state = self._after_behaviour(fsm, state, failed)
        if self.roles.withdraw_queries():  # stopping: no participant answers for nobody
            self.persist()
        if self._here and not self._dispatch_here():
            yield 0.0
        self.dispatch()

    def _after_behaviour(self, fsm: FSM, state: str, failed: bool) -> str:
        """The state after ``state`` ended: the FSM's next (paper §3.2: the first arc whose
        initial condition holds), or the initial one after its transition function raised
        (``failed``); recorded (services/runtime/fsm_record.py)."""
        record = self.fsm_record
        if failed:
            if record is not None:
                record.entered(fsm.initial, "error")
            return fsm.initial
        arc = fsm.next_arc(state)
        if record is not None:
            record.entered(arc.target, "arc", arc.source, arc.label)
        return arc.target
