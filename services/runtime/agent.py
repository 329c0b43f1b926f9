"""The embodied agent's control subsystem c_j (paper §3.2, eq. 2) on a transport; the manual:
docs/agents.md and docs/spec.md ("Protocol roles").

A subclass declares its ``name`` (as in the specification), creates its memory in
``__init__`` and builds its FSM of behaviours in :meth:`Agent.build_fsm`. The runtime provides:

- the transmission input buffer ``x`` (:class:`Received` communicates) and the receptor input
  buffer ``r`` (its own receptors' events: human text, executor results); :meth:`send` /
  :meth:`reply` fill the output buffer dispatched after each step;
- checks against the specification (paper §4 steps 3–4; FIPA SC00061, SC00026/27/35): a
  received communicate outside the agent's interface, malformed, in a language or ontology it
  does not accept, whose content does not decode, or not allowed in its conversation's protocol
  state is answered ``not-understood`` and dropped; one the agent may not send raises
  :class:`SpecViolation`. Each is counted (``counters``, services/runtime/limits.py
  ``REJECT_REASONS``) and logged (at most ``LOG_BURST`` per ``LOG_WINDOW_S``); nothing a peer
  sends stops the agent; at most ``MAX_OPEN_CONVERSATIONS_PER_PEER`` open conversations a peer;
- agents of other platforms (``local@platform``) checked as the specification's external role
  (docs/gateway.md); ``counters`` on request (``roco/counters/ask``; ``roco status``);
- the protocol state of every conversation (services/runtime/protocol_state.py), reply-by
  deadlines (services/runtime/replies.py), at-least-once delivery where asked (``retry_s``)
  and at-most-once handling (services/runtime/dedup.py; docs/recovery.md);
- peer liveliness (:meth:`Agent.peer_changed`), readiness (:attr:`Agent.ready`,
  :attr:`Agent.on_ready`), persistence after every step (:meth:`Agent.persist`,
  services/runtime/state_store.py; :meth:`Agent.on_restored`), its clocks and identifiers
  (:attr:`Agent.sources`, services/runtime/sources.py);
- one thread at a time runs the elementary actions: the agent's own or, while it is idle, the
  transport's receiving thread (``RECEIVE_INLINE = False`` keeps every step on the agent's).

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
from typing import Any, ClassVar, NoReturn

import msgspec

from services.runtime import fsm_record, keys
from services.runtime.admission import (
    BAD_KEY,
    COPY,
    NO_CONVERSATION_ID,
    RECEIVED_COUNTER,
    REFUSED,
    TOO_MANY,
    UNDECODABLE,
    Admission,
    Gate,
    step,
)
from services.runtime.behaviour import FSM, Arc, Behaviour, once, periodic
from services.runtime.clock import FleetClock, decode_sim_time, encode_sim_time
from services.runtime.dedup import Dedup
from services.runtime.emission import SENT_COUNTER, Outbox, Outgoing
from services.runtime.heap import give_back_freed_heap
from services.runtime.hooks import Hooks, load_hooks
from services.runtime.human import (
    FINAL_REPORTS,
    MAX_LINE_CHARS,
    NOTICES_PER_S,
    HumanInput,
    HumanReport,
    ReportKind,
    RequestKind,
)
from services.runtime.intake import Refusal
from services.runtime.limits import MAX_OPEN_CONVERSATIONS_PER_PEER
from services.runtime.lookups import Followed, Lookups
from services.runtime.person import PersonFace, Told
from services.runtime.protocol_state import ProtocolStates
from services.runtime.replies import Pending, PendingReplies
from services.runtime.roles import Conversation, RoleDecl, Roles
from services.runtime.sources import SYSTEM, Sources
from services.runtime.state_store import NO_DATA, KeptConversations, StateFile
from services.runtime.transport import Transport
from services.runtime.values import RESEND_ON_RETURN, Received, SpecViolation
from services.spec.model import Interface, SystemSpec, asked, default_spec, interface
from services.spec.protocol_defs import machine_of, streams
from shared.fipa_codec import (
    AgentIdentifier,
    Communicate,
    DecodeError,
    Performative,
    encode,
)
from shared.fipa_codec.batch import BATCH_HEADS, unpack
from shared.fipa_codec.languages import language_of
from shared.fipa_codec.protocols import (
    INITIATOR,
    is_terminal_report,
)
from shared.settings import Settings

__all__ = [
    "FINAL_REPORTS",
    "FSM",
    "MAX_LINE_CHARS",
    "NOTICES_PER_S",
    "RESEND_ON_RETURN",
    "Agent",
    "Arc",
    "Behaviour",
    "HumanInput",
    "HumanReport",
    "PersonFace",
    "Received",
    "ReportKind",
    "RequestKind",
    "SpecViolation",
    "Told",
    "Transport",
    "encode_sim_time",
    "keys",
    "once",
    "periodic",
]
"""An agent's API besides its roles (services/runtime/roles/): the agent, its behaviours
(services/runtime/behaviour.py), a received communicate and the agent's own send errors
(services/runtime/values.py), the Zenoh keys (services/runtime/keys.py), the simulation
clock's encoding (services/runtime/clock.py) and the person's side of an interface agent
(services/runtime/human.py, services/runtime/person.py), re-exported so that an agent imports
from two runtime modules."""

_FOLLOWED_MAX = 1024
_ALIVE = "\x00alive"
"""Input-queue key of a peer liveliness event (never a Zenoh key)."""
_COUNTERS = "\x00counters"
"""Input-queue key of a request for the agent's counters (``roco/counters/ask``)."""
LOG_BURST = 50
"""Warnings about rejected input logged per :data:`LOG_WINDOW_S` before the rest are only
counted (and their number logged once the window ends)."""
LOG_WINDOW_S = 10.0
INLINE_OUTPUT_MAX = 32
"""Communicates a step taken in on a receiving thread may put from that thread; a step that
sends more (a stream) is dispatched by the agent's own thread (see :meth:`Agent._take_here`)."""
INLINE_GAP_S = 200e-6
"""On a transport that cannot tell whether more input waits (no ``more_waiting``): a
communicate that arrives within this time (s) of the one before it is handed to the agent's
thread, which takes what has arrived together in one step (a stream), instead of being taken in
on the receiving thread one step each (see :meth:`Agent._take_here`)."""
INLINE_BUDGET_S = 0.05
"""Longest a step may compute on a receiving thread (s of the thread's CPU time): an agent whose
step computed longer takes its input on its own thread from then on. CPU time, not wall time:
with 100 agent processes on 2 cores a 100 µs step waits tens of ms for a core at times, and a
wall-time budget turned inline receiving off for a third of them (docs/benchmarks.md, "Fewer
wake-ups per communicate")."""


OVERRIDABLE = frozenset(
    {
        "ROLES",
        "NOTE",
        "period",
        "RECEIVE_INLINE",
        "build_fsm",
        "setup",
        "peer_changed",
        "persist",
        "on_restored",
    }
)
"""The names of :class:`Agent` an agent's class may define again: its declarations and the hooks
the runtime calls. Any other name of the runtime's that an agent's class defines replaces the
runtime's own (an agent's helper named ``_ended`` would), which ``roco spec verify-code``
refuses (services/spec_check/code_check.py)."""


class Agent:
    """Base class of every roco agent (a purely computational agent: control subsystem only,
    paper §5.5). Subclasses set ``name`` and implement :meth:`build_fsm`."""

    name: ClassVar[str]
    ROLES: ClassVar[tuple[RoleDecl, ...] | None] = None
    """The protocol roles the agent plays (services/runtime/roles/), compared with its
    interface in the specification when it starts (RoleMismatch, one line, when they differ).
    None: the agent declares none and handles its input buffer itself (checked at run time
    only)."""
    NOTE: ClassVar[type[msgspec.Struct] | None] = None
    """What the agent keeps across a restart besides the conversations of its roles declared
    with ``keep`` (a msgspec Struct whose fields all have defaults): the runtime builds
    :attr:`note` from it before :meth:`build_fsm`, writes it with those conversations after
    every step that changed it, and gives it back before :meth:`on_restored` (docs/recovery.md)."""
    period: ClassVar[float] = 0.1
    """Sampling period (s) of communication states: the longest a waiting behaviour blocks (a
    periodic behaviour blocks no longer than until its next period is due:
    services/runtime/behaviour.py ``periodic``)."""
    RECEIVE_INLINE: ClassVar[bool] = True
    """While the agent is idle (its behaviour blocked for input), a communicate is taken in,
    and the next elementary actions run, on the transport's thread it arrived on, instead of
    being handed to the agent's thread (one thread wake-up less per receive). False:
    an agent whose steps must run on one thread (thread-bound resources)."""

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
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
        self.i = 0
        self.state = ""
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
        """Set once, on the agent's thread: :meth:`setup` has run, the liveliness token is
        declared and every agent of :attr:`asks` has been seen. It stays set when one of them
        disappears later (that one's own readiness says so)."""
        self.on_ready: Callable[[str], None] | None = None
        """Called once when the agent becomes :attr:`ready`, with one line saying so (the process
        writes it to its ready file, services/runtime/main.py); None: nothing is called."""
        self._set_up = False  # setup() has run and the liveliness token is declared
        self.max_open_per_peer = MAX_OPEN_CONVERSATIONS_PER_PEER
        """Open conversations a peer may have with this agent before a new one is refused."""
        self._log_window = (0.0, 0)  # (window start, monotonic s; warnings logged in it)
        self._log_suppressed = 0
        self._outgoings: dict[tuple[str, Performative, str, type], Outgoing] = {}
        """:meth:`outgoing` per (receiver, performative, protocol, content type)."""
        self._streaming: dict[tuple[str, Performative], bool] = {}
        """:meth:`_streams` per (protocol, performative)."""
        self.roles = Roles(self, self.ROLES or (), check=self.ROLES is not None)
        """The agent's protocol roles and their open conversations (services/runtime/roles/)."""
        self._y: list[tuple[str, bytes]] = []
        self._outbox = Outbox(
            self,
            self.name,
            self.aid,
            self.protocol_states,
            self.dedup,
            self.pending_replies,
            self._outgoings,
            self._y,
            self.counters,
        )
        """Sends every communicate of :meth:`send` (services/runtime/emission.py), into ``_y``."""
        self._gate = Gate(
            self,
            self.lookups,
            self.dedup,
            self.protocol_states,
            self.pending_replies,
            self.x,
            self.counters,
            Received,
            frozenset(("r", _ALIVE, _COUNTERS)),
        )
        """Takes every communicate in (services/runtime/admission.py), into ``x``."""
        self._y_taken = 0
        """How much of ``_y`` taking inputs in put there (answers a failing behaviour keeps)."""
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
            self.RECEIVE_INLINE
            and bool(getattr(transport, "inline_receive", False))
            and Settings.from_env(only=("receive",)).receive != "agent-thread"
        )
        self._stop = threading.Event()
        self.note: Any = self.NOTE() if self.NOTE is not None else None
        """The agent's :attr:`NOTE`, kept across a restart by the runtime (None: none)."""
        self.fleet_clock = FleetClock(self.sources.monotonic)
        """The clock the FSM's periodic behaviours run on (services/runtime/clock.py): the
        simulation's pace once ag_ex's ``roco/sim/clock`` is heard (:meth:`bind`), the wall
        clock's before and in real time."""
        self.fsm = self.build_fsm()
        self._bind_timers()
        self.fsm_record = fsm_record.for_agent(self.name)
        """Where the agent records its FSM's transitions and its time-outs
        (services/runtime/fsm_record.py); None: neither a run folder nor a tap folder is set."""
        keeps = self.roles.keeps or self.NOTE is not None
        self._kept_conversations: StateFile[KeptConversations] | None = (
            StateFile.for_agent(self.name, KeptConversations) if keeps else None
        )
        """Where the runtime keeps the conversations of the roles declared with ``keep`` and
        :attr:`note` (services/runtime/state_store.py); None: the agent keeps neither."""
        self._kept_last: KeptConversations | None = None  # what persist last wrote
        self._take_back()

    # ---- to be provided by agents -------------------------------------------------------
    def build_fsm(self) -> FSM:
        """The agent's FSM of behaviours (paper §3.2). Called once, in ``__init__``."""
        raise NotImplementedError

    def setup(self) -> None:
        """Runs once after the transport is bound, before the first behaviour."""

    def peer_changed(self, peer: str, alive: bool) -> None:
        """``peer``'s liveliness token appeared (``alive``; also for every token present at
        start) or disappeared: its process ended or lost its session. Runs on the agent's
        thread between steps; may send. Unanswered retransmittable communicates to a peer
        that appears are retransmitted at once by the runtime."""

    def persist(self) -> None:
        """Runs after every step, once its output buffer is dispatched (so what it has said is
        what it keeps): the open conversations of the roles declared with ``keep``
        (services/runtime/roles/ :meth:`Roles.kept`) and :attr:`note`, written when they
        changed; the file is encoded only then (an opening kept is not encoded again every
        step). An agent whose data of a kept conversation follows from its state sets it here
        before calling this (a_ta: the leaf step it is in). Raises OSError when the state
        folder cannot be written."""
        if self._kept_conversations is None:
            return
        kept = self.roles.kept()
        if self.note is not None:
            kept.note = msgspec.Raw(msgspec.json.encode(self.note))
        if kept != self._kept_last:  # compared field by field: the openings are the same bytes
            self._kept_conversations.save(kept)
            self._kept_last = kept

    def on_restored(self, conversation: Conversation) -> None:
        """A conversation of a role declared with ``keep``, taken back after a restart (when
        the agent is built, before :meth:`setup`): in its protocol state, with its
        :attr:`~services.runtime.roles.Conversation.data` (docs/recovery.md). The agent
        rebuilds what it holds of it here. Raising TypeError or ValueError (e.g. the opening
        carries content of another type: ``conversation.opening_content(kind)``) drops it."""

    def _take_back(self) -> None:
        """Take back the conversations kept before a restart (:meth:`on_restored` each)."""
        kept = self._kept_conversations.load() if self._kept_conversations is not None else None
        if kept is None:
            return
        if self.NOTE is not None and bytes(kept.note) != bytes(NO_DATA):
            try:
                self.note = msgspec.json.decode(kept.note, type=self.NOTE)
            except (msgspec.DecodeError, msgspec.ValidationError) as exc:
                self.log.warning("the kept note does not decode (%s): a new one is begun", exc)
        n = 0
        for conv in self.roles.take_back(kept):
            try:
                self.on_restored(conv)
            except (TypeError, ValueError) as exc:
                self.log.warning(
                    "a kept %s conversation cannot be taken back (%s): dropped", conv.decl.protocol, exc
                )
                conv.forget()
                continue
            n += 1
        if n:
            self.log.info(
                "took back %d kept conversation(s) from %s",
                n,
                self._kept_conversations.path if self._kept_conversations else "",
            )

    # ---- sending -------------------------------------------------------------------------
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
        (and at once when ``to`` reappears; :data:`RESEND_ON_RETURN`: only then); use it
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

    def outgoing(
        self, to: str, performative: Performative, protocol: str, content: msgspec.Struct | None
    ) -> Outgoing:
        """What every communicate to ``to`` of ``performative`` in ``protocol`` carrying a term
        of ``content``'s type shares (:class:`Outgoing`), checked against the interface the
        first time and kept (at most ``_FOLLOWED_MAX``); raises as :meth:`send`, keeping
        nothing, while the interface forbids it."""
        route = (to, performative, protocol, type(content))
        found = self._outgoings.get(route)
        if found is None:
            found = self._route(to, performative, protocol, content)
            if len(self._outgoings) < _FOLLOWED_MAX:
                self._outgoings[route] = found
        return found

    def _route(
        self, to: str, performative: Performative, protocol: str, content: msgspec.Struct | None
    ) -> Outgoing:
        """:meth:`outgoing` found anew: the channel to ``to`` (SpecViolation: none), the
        content's language (ContentError: none), the interface's checks (:meth:`_check_send`),
        whether ``performative`` opens a conversation that streams (:meth:`_streams`)."""
        channel = self.lookups.channel(to)
        if channel is None:
            raise SpecViolation(f"{self.name}: no channel to {to}")
        language = language_of(content) if content is not None else None
        self._check_send(
            to,
            performative.value,
            protocol,
            language.name if language is not None else None,
            type(content).__name__ if content is not None else None,
        )
        return Outgoing(
            self.lookups.key(channel.name, to),
            (self.lookups.aid(to),),
            language.name if language is not None else None,
            language.ontology if language is not None else None,
            self.lookups.followed(to, protocol),
            str(protocol),  # a plain str: a subclass's (ProtocolName) is checked by a call per send
            self._streams(protocol, performative),
        )

    def _streams(self, protocol: str, performative: Performative) -> bool:
        """``performative`` opens a conversation of ``protocol`` that streams: many replies
        answer it (fipa-subscribe's informs, coordinate's reports; from the state machine).
        Asked once per pair (raises SpecError, keeping nothing, for a protocol without a
        state machine)."""
        found = self._streaming.get((protocol, performative))
        if found is None:
            found = False
            if protocol in self.spec.protocols:
                machine = machine_of(self.spec, protocol)
                opens = machine.next_state(machine.initial, INITIATOR, performative) is not None
                found = streams(machine) and opens
            self._streaming[(protocol, performative)] = found
        return found

    def _out(self, to: str, in_reply_to: str | None, key: str, payload: bytes) -> None:
        """Put an encoded communicate into the output buffer; remember it as an answer to
        ``to``'s ``in_reply_to`` so that a copy of that communicate gets it again."""
        if in_reply_to is not None:
            self.dedup.answered(to, in_reply_to, key, payload)
        self._y.append((key, payload))

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
        in-reply-to = its reply-with (other arguments and errors as :meth:`send`, whose work
        it hands to the same ``Outbox.send``)."""
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
        """Answer ``to`` with ``failure`` or ``refuse`` whose content is ``reason`` as UTF-8
        text (FIPA SC00037: the reason a person or agent can read). Raises SpecViolation when
        the interface does not allow that performative in ``to``'s protocol."""
        protocol = to.msg.protocol or ""
        self._check_send(to.sender, performative.value, protocol, None)
        channel = self.lookups.channel(to.sender)
        assert channel is not None  # _check_send found a kind, so a channel exists
        msg = Communicate(
            performative=performative,
            sender=self.aid,
            receiver=(self.lookups.aid(to.sender),),
            content=reason.encode(),
            encoding="utf-8",
            protocol=protocol,
            conversation_id=to.msg.conversation_id,
            in_reply_to=to.msg.reply_with,
        )
        self._follow_send(to.sender, msg, self.lookups.followed(to.sender, protocol))
        self._out(to.sender, msg.in_reply_to, self.lookups.key(channel.name, to.sender), encode(msg))
        self.counters[SENT_COUNTER[performative]] += 1

    def not_understood(
        self, sender: str, channel: str, why: str, about: Communicate | None, reason: str = "unhandled"
    ) -> None:
        """Answer ``sender`` with not-understood; content is the reason as UTF-8 text.

        ``reason`` is the counter it is counted under (``rejected.<reason>``; the names are in
        services/runtime/limits.py ``REJECT_REASONS``). The not-understood ends ``about``'s
        conversation (FIPA SC00037 §3.12): from now on the runtime no longer follows its
        protocol state, and a conversation this agent opened ends through its handler
        (:meth:`Roles.not_understood_sent`). A not-understood is never answered with one (no
        loops)."""
        self.counters["rejected"] += 1
        self.counters[f"rejected.{reason}"] += 1
        cid = about.conversation_id if about is not None else None
        self._warn_rejected("not-understood to %s (conversation %s): %s", sender, cid, why)
        if about is not None and about.performative is Performative.NOT_UNDERSTOOD:
            return  # never answer a not-understood with one: no loops
        if about is not None and cid is not None and self.protocol_states.get(sender, cid) is not None:
            self._follow(sender, cid, about.protocol, Performative.NOT_UNDERSTOOD, True, None)
        msg = Communicate(
            performative=Performative.NOT_UNDERSTOOD,
            sender=self.aid,
            receiver=(self.lookups.aid(sender),),
            content=why.encode(),
            encoding="utf-8",
            protocol=about.protocol if about else None,
            conversation_id=about.conversation_id if about else None,
            in_reply_to=about.reply_with if about else None,
        )
        self._out(sender, msg.in_reply_to, self.lookups.key(channel, sender), encode(msg))
        if about is not None and cid is not None:
            self.roles.not_understood_sent(sender, channel, about, why)

    def _warn_rejected(self, fmt: str, *args: object) -> None:
        """Log a warning about rejected input, at most :data:`LOG_BURST` per
        :data:`LOG_WINDOW_S`; the number left out is logged when the next window begins."""
        now = self.sources.monotonic()
        start, logged = self._log_window
        if now - start >= LOG_WINDOW_S:
            if self._log_suppressed:
                self.log.warning(
                    "%d more warnings about rejected input in %.0f s not logged",
                    self._log_suppressed,
                    LOG_WINDOW_S,
                )
            start, logged, self._log_suppressed = now, 0, 0
        if logged < LOG_BURST:
            self.log.warning(fmt, *args)
            logged += 1
        else:
            self._log_suppressed += 1
        self._log_window = (start, logged)

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

    def _check_send(
        self, to: str, performative: str, protocol: str, language: str | None, term: str | None = None
    ) -> None:
        kind = self.lookups.sends(to, performative, protocol)
        if kind is None:
            self.send_violation(None, f"{self.name}: may not send {performative} to {to} in {protocol}")
        if language is not None and kind.languages and language not in kind.languages:
            self.send_violation(
                None,
                f"{self.name}: {performative} to {to} in {protocol} must use "
                f"{'/'.join(kind.languages)}, not {language}",
            )
        if term is not None and kind.contents and term not in kind.contents:
            self.send_violation(
                None,
                f"{self.name}: {performative} to {to} in {protocol} may carry "
                f"{', '.join(kind.contents)}, not {term}",
            )

    def send_violation(self, conversation_id: str | None, text: str) -> NoReturn:
        """Count, log and raise a violation the agent's own code is about to commit."""
        self.counters["send_violations"] += 1
        self.log.warning("refused to send (conversation %s): %s", conversation_id, text)
        raise SpecViolation(text)

    def _follow_send(self, to: str, msg: Communicate, followed: Followed | None) -> None:
        """Follow a communicate about to be sent in its conversation's protocol state
        (``followed``: its state machine and the agent's role, ``Lookups.followed``); raises
        SpecViolation when the state does not allow it."""
        cid = msg.conversation_id
        if followed is None or cid is None:
            return
        performative = msg.performative
        states = self.protocol_states
        outcome, why = step(
            states, self.name, to, cid, followed, performative, True, is_terminal_report(msg), msg
        )
        if outcome != "step":
            self.conversation_stepped(to, cid, performative, outcome)
        if why is not None:
            self.send_violation(
                msg.conversation_id,
                f"{self.name}: may not send {msg.performative.value} to {to} in conversation "
                f"{msg.conversation_id}: {why}",
            )

    def _follow(
        self,
        peer: str,
        conversation_id: str | None,
        protocol: str | None,
        performative: Performative,
        sent: bool,
        terminal: bool | None,
        msg: Communicate | None = None,
    ) -> str | None:
        """Advance the protocol state of conversation ``conversation_id`` with ``peer`` by one
        communicate (``sent`` by this agent, else received; ``msg`` the communicate, whose
        reply-with and in-reply-to tell what it answers). Returns None when the state allows
        it (or the conversation is not followed: no conversation-id, a protocol without a state
        machine), else the reason."""
        if conversation_id is None or protocol is None:
            return None
        followed = self.lookups.followed(peer, protocol)
        if followed is None:
            return None
        return self._step_conversation(peer, conversation_id, followed, performative, sent, terminal, msg)

    def _step_conversation(
        self,
        peer: str,
        conversation_id: str,
        followed: Followed,
        performative: Performative,
        sent: bool,
        terminal: bool | None,
        msg: Communicate | None = None,
    ) -> str | None:
        """:meth:`_follow` in a followed conversation: ``followed`` is its state machine and
        the agent's role in it (``Lookups.followed``; services/runtime/admission.py ``step``)."""
        outcome, why = step(
            self.protocol_states,
            self.name,
            peer,
            conversation_id,
            followed,
            performative,
            sent,
            terminal,
            msg,
        )
        if outcome != "step":
            self.conversation_stepped(peer, conversation_id, performative, outcome)
        return why

    def conversation_stepped(
        self, peer: str, conversation_id: str, performative: Performative, outcome: str
    ) -> None:
        """Count a communicate that crossed another on the wire."""
        if outcome == "crossing":
            self.counters["crossings"] += 1

    def emit(self, key: str, payload: bytes) -> None:
        """Put a payload for one of the agent's effectors (a non-FIPA key, e.g. a_hi's
        ``roco/human/out``), or an already encoded communicate sent again as it was, into the
        output buffer."""
        self._y.append((key, payload))

    # ---- receiving -----------------------------------------------------------------------
    def post(self, event: Any) -> None:
        """Put a receptor event into the agent (thread-safe; wakes a waiting behaviour)."""
        self._put_input(("r", event))

    def _put_input(self, item: tuple[str, Any]) -> None:
        """Hand an input to the agent's thread (any thread; wakes it)."""
        with self._arrived_lock:
            self._inbox.append(item)
            if self._sleepers:
                self._arrived.notify()

    def _put_inputs(self, items: list[tuple[str, Any]]) -> None:
        """Hand several inputs, in order, to the agent's thread at once (any thread; wakes it)."""
        with self._arrived_lock:
            self._inbox.extend(items)
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
            self._put_inputs([(key, part) for part in unpack(payload)])
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

    def _bind_timers(self) -> None:
        """Put the FSM's periodic behaviours on :attr:`fleet_clock` (a timer that asks for the
        wall clock, or gives its own clock, keeps it: services/runtime/behaviour.py ``Every``)."""
        for b in self.fsm.states.values():
            if b.timer is not None:
                b.timer.bind(self.fleet_clock, self.sources.monotonic)

    def _on_sim_clock(self, key: str, payload: bytes) -> None:
        with contextlib.suppress(ValueError):  # not a simulation time: the clock runs on as it did
            self.fleet_clock.mark(decode_sim_time(payload))  # thread-safe: no input to take in

    def _on_counters_ask(self, key: str, payload: bytes) -> None:
        self._put_input((_COUNTERS, None))  # Zenoh thread: enqueue only

    def _on_alive(self, key: str, alive: bool) -> None:
        name = keys.alive_agent(key)
        if name is not None:  # a token that carries no agent name is none of an agent
            self._put_input((_ALIVE, (name, alive)))  # Zenoh thread: enqueue only

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
        if len(self._y) > INLINE_OUTPUT_MAX:
            return False
        declared = self._declared
        return declared is None or all(declared(key) for key, _ in self._y)

    def _acquire_blocking(self, timeout: float) -> Generator[float, None, None]:
        """Acquire new inputs into x and r, blocking up to ``timeout`` (s) for the first: the
        elementary actions are suspended (yield the time to wait) until an input arrives or the
        time passes, then :meth:`_acquire`."""
        deadline = self.pending_replies.next_deadline()
        if deadline is not None:
            timeout = max(0.0, min(timeout, deadline - self.sources.time()))
        if timeout > 0 and not self._inbox:
            yield timeout
        elif self._here:  # actions that go on without waiting go on on the agent's thread
            yield 0.0
        self._acquire()

    def _acquire(self, timeout: float = 0.0) -> None:
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
        self._y_taken = len(self._y)  # so do the answers to it (not-understood, copies again)
        if now >= self.pending_replies.earliest:  # a deadline or a retransmission may be due
            self._overdue(now)

    def _overdue(self, now: float) -> None:
        """Retransmit what is due at POSIX time ``now``; end the conversations whose reply-by
        deadline passed with a local failure (see :meth:`_acquire`)."""
        for p in self.pending_replies.due(now):
            self.counters["retransmitted"] += 1
            self.log.info(
                "retransmitting %s to %s (conversation %s, #%d)",
                p.reply_with,
                p.peer,
                p.conversation_id,
                p.retransmissions,
            )
            self._y.append((p.key, p.payload))
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

    def _take(self, key: str, payload: Any) -> None:
        """Take one input in, as :meth:`_acquire` does (tests and tools hand inputs over)."""
        self._gate.take_all(deque(((key, payload),)), self.max_open_per_peer)

    def take_event(self, key: str, payload: Any) -> None:
        """Take in an input of the runtime's own: a command for ``r``, a peer's liveliness, a
        request for the counters (services/runtime/admission.py ``Gate.take_all``)."""
        if key == "r":
            self.r.append(payload)
        elif key == _ALIVE:
            self._peer_event(*payload)
        else:
            self._y.append((keys.counters_key(self.name), self.counters_report()))

    def take_raised(self, key: str) -> None:
        """Taking in the communicate on ``key`` raised: counted, its traceback logged (no input
        may stop the agent)."""
        self.counters["rejected.internal"] += 1
        self.log.exception("taking in a communicate on %s raised", key)

    def not_taken(self, found: Admission) -> None:
        """A communicate :func:`admit` did not take (``found.verdict``): counted, and answered
        (not-understood, a refuse, or the answers to its original sent again) or dropped."""
        verdict, sender, channel, msg = found.verdict, found.sender, found.channel, found.msg
        if verdict == BAD_KEY:
            self.counters["bad_key"] += 1
            self.counters["rejected.bad_key"] += 1
            return
        if verdict == UNDECODABLE:
            assert found.error is not None
            self._undecodable(sender, channel, found.error, found.copy)
            return
        assert msg is not None
        if verdict == COPY:
            self._copy(sender, msg)
            return
        self.counters[RECEIVED_COUNTER[msg.performative]] += 1
        if verdict == REFUSED:
            assert found.refusal is not None
            self._refuse(sender, channel, msg, found.refusal)
        elif verdict == NO_CONVERSATION_ID:
            needs = f"{msg.performative.value} in protocol {msg.protocol} needs a conversation-id"
            self.not_understood(sender, channel, needs, msg, "no_conversation_id")
        elif verdict == TOO_MANY:
            self._refuse_new_conversation(sender, channel, msg, found.content)
        else:
            self._out_of_state(sender, channel, msg, found.why)

    def _undecodable(self, sender: str, channel: str, exc: DecodeError, copy: bool) -> None:
        """A payload from ``sender`` that does not decode (``exc``): a copy of one seen already
        is counted as a duplicate; otherwise it is answered not-understood (malformed, or
        oversized)."""
        if copy:
            self.counters["duplicates"] += 1
            return
        bad = "oversized" if exc.oversized else "malformed"
        self.not_understood(sender, channel, f"{bad} communicate: {exc.reason}", None, bad)

    def _copy(self, sender: str, msg: Communicate) -> None:
        """A byte-identical copy of ``msg`` came again from ``sender``: dropped, and the
        answers sent to it published again."""
        self.counters["duplicates"] += 1
        again = self.dedup.answers(sender, msg.reply_with)
        self.log.info(
            "copy of %s from %s (conversation %s) dropped; %d answer(s) sent again",
            msg.performative.value,
            sender,
            msg.conversation_id,
            len(again),
        )
        self.counters["replayed"] += len(again)
        self._y.extend(again)

    def _refuse(self, sender: str, channel: str, msg: Communicate, refusal: Refusal) -> None:
        """Answer ``msg`` not-understood for ``refusal`` (a term its kind may not carry is
        counted as a ``content_violations`` too)."""
        if refusal.counter == "content_type":
            self.counters["content_violations"] += 1
        self.not_understood(sender, channel, refusal.reason, msg, refusal.counter)

    def _out_of_state(self, sender: str, channel: str, msg: Communicate, why: str) -> None:
        """The conversation's protocol state does not allow ``msg`` (``why``): a late reply to
        an earlier opening of the conversation is dropped; anything else is a protocol
        violation, answered not-understood."""
        if self.roles.answers_earlier_opening(sender, msg):
            # not-understood would end (FIPA SC00037 §3.12) the conversation opened anew, and
            # with it what the peer sends in it next (a_km restarted, subscribed again, and
            # lost a_ta's fresh observation after answering a stale update not-understood)
            self.counters["late_replies"] += 1
            self.log.info(
                "%s from %s in conversation %s dropped: it answers an earlier opening (%s)",
                msg.performative.value,
                sender,
                msg.conversation_id,
                msg.in_reply_to,
            )
            return
        self.counters["protocol_violations"] += 1
        self._warn_rejected(
            "protocol violation by %s in conversation %s: %s", sender, msg.conversation_id, why
        )
        self.not_understood(sender, channel, why, msg, "protocol_state")

    def _refuse_new_conversation(
        self, sender: str, channel: str, msg: Communicate, content: msgspec.Struct | None
    ) -> None:
        """``sender`` opens one more conversation while it has ``max_open_per_peer`` open with
        this agent: follow the opening communicate, then ``refuse`` it (FIPA SC00037 §3.17;
        the reason as UTF-8 text), or answer ``not-understood`` where the protocol has no
        refuse for this agent. A communicate that does not open a conversation is a protocol
        violation as usual."""
        why = self._follow(
            sender, msg.conversation_id, msg.protocol, msg.performative, False, is_terminal_report(msg), msg
        )
        if why is not None:
            self.counters["protocol_violations"] += 1
            self.not_understood(sender, channel, why, msg, "protocol_state")
            return
        text = (
            f"{sender} has {self.protocol_states.open_with(sender) - 1} conversations open with "
            f"{self.name}; at most {self.max_open_per_peer}"
        )
        protocol = msg.protocol or ""
        may_refuse = any(
            k.receiver == self.spec.role_of(sender)
            and k.performative == Performative.REFUSE.value
            and k.protocol == protocol
            for k in self.interface.sends
        )
        if may_refuse:
            try:
                self.fail(Received.of(msg, content, channel), Performative.REFUSE, text)
            except SpecViolation:  # the protocol's state machine has no refuse here
                may_refuse = False
            else:
                self.counters["rejected.too_many_conversations"] += 1
                self._warn_rejected("refused conversation %s: %s", msg.conversation_id, text)
        if not may_refuse:
            self.not_understood(sender, channel, text, msg, "too_many_conversations")

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
        self.peer_changed(peer, alive)

    def _check_ready(self) -> None:
        """Become :attr:`ready` when set up with every agent of :attr:`asks` seen (once)."""
        if self.ready or not self._set_up or not self.peers.issuperset(self.asks):
            return
        self.ready = True
        seen = f"; {', '.join(self.asks)} seen" if self.asks else ""
        self.log.info("ready: roles set up%s", seen)
        if self.on_ready is not None:
            self.on_ready(f"{self.name} ready: roles set up{seen}")

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
            why = self._follow(peer, conversation_id, protocol, performative, sent, False)
            if why is not None:
                self.protocol_states.rollback()
                raise SpecViolation(f"cannot restore conversation {conversation_id} with {peer}: {why}")
        tracker = self.protocol_states.get(peer, conversation_id)
        if tracker is not None and opening_reply_with:
            tracker.opening_reply_with = opening_reply_with
        self.protocol_states.commit()

    # ---- the loop -----------------------------------------------------------------------
    def _dispatch(self) -> None:
        """Put the output buffer (communicates that one step sends in a row to one receiver in
        one batch, :attr:`batch_puts`); what it held is sent: its protocol states are kept
        (services/runtime/emission.py ``Outbox.dispatch``)."""
        self._outbox.dispatch(self.transport.publish, self.batch_puts)
        self._y_taken = 0

    def bind(self) -> None:
        """Subscribe the input buffer and watch the peers' liveliness; hear the simulation's
        time (:attr:`fleet_clock`) unless the fleet runs in real time (``ROCO_REALTIME``). The
        agent's own liveliness token is declared by :meth:`run`, after :meth:`setup`: a peer
        (or a person) that sees it finds every subscription of the agent in place."""
        self.transport.subscribe(keys.inbox_key(self.name), self._on_payload)
        self.transport.subscribe(keys.COUNTERS_ASK, self._on_counters_ask)
        self.transport.watch(keys.ALIVE_ALL, self._on_alive)
        if not Settings.from_env(only=("realtime",)).realtime:
            self.transport.subscribe(keys.SIM_CLOCK, self._on_sim_clock)

    def stop(self) -> None:
        """End :meth:`run` after the current step (any thread; also a signal handler)."""
        self._stop.set()
        self._put_input(("r", None))

    @property
    def stopping(self) -> bool:
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
        begins them (:meth:`setup`, the liveliness token); each later one goes on with what was
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
        self.setup()
        self.transport.announce(keys.alive_key(self.name))
        self._set_up = True
        self._check_ready()
        self._dispatch()
        state = self.fsm.initial
        if self.fsm_record is not None:
            self.fsm_record.declared(self.fsm, f"{type(self).__module__}:{type(self).__qualname__}")
            self.fsm_record.entered(state, "start")
        while not self._stop.is_set():
            self.state = state
            behaviour = self.fsm.states[state]
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
                    del self._y[self._y_taken :]  # the answers taking inputs in gave stay
                    self.protocol_states.rollback()  # what was dropped was never sent
                    failed = True
                    break
                if self._here and not self._dispatch_here():
                    yield 0.0
                self._dispatch()
                self.persist()
                self.i += 1
                # a communication state blocks for new input only while it has nothing to end on
                # (a periodic one no longer than until its next period is due)
                done = behaviour.error() or behaviour.terminal()
                wait = self.period if behaviour.waits and not done else 0.0
                if wait and behaviour.timer is not None:
                    wait = min(wait, behaviour.timer.wall_left())
                yield from self._acquire_blocking(wait)
                if done or behaviour.error() or behaviour.terminal():
                    break
            if self._stop.is_set():
                break
            state = self._after_behaviour(state, failed)
        if self.roles.withdraw_queries():  # stopping: no participant answers for nobody
            self.persist()
        if self._here and not self._dispatch_here():
            yield 0.0
        self._dispatch()

    def _after_behaviour(self, state: str, failed: bool) -> str:
        """The state after ``state`` ended: its FSM's next (paper §3.2: the first arc whose
        initial condition holds), or the initial one after its transition function raised
        (``failed``); recorded (services/runtime/fsm_record.py)."""
        record = self.fsm_record
        if failed:
            if record is not None:
                record.entered(self.fsm.initial, "error")
            return self.fsm.initial
        arc = self.fsm.next_arc(state)
        if record is not None:
            record.entered(arc.target, "arc", arc.source, arc.label)
        return arc.target

    # ---- helpers for behaviours ---------------------------------------------------------
    def handle_received(self) -> None:
        """Route every communicate in the input buffer ``x`` to its protocol role and the
        agent's handler (services/runtime/roles/), oldest first."""
        while self.x:
            self.roles.take(self.x.popleft())
