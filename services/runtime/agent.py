"""The author's side of an agent (paper §3.2, eq. 2: the control subsystem c_j): its
declarations, its hooks and handlers, and the small context its code uses; the manual:
docs/agents.md and docs/spec.md ("Protocol roles").

A subclass declares its ``name`` (as in the specification), creates its memory in
``__init__`` before calling ``super().__init__``, declares its protocol roles (``ROLES``, with
:func:`~services.runtime.roles.handles` methods) and builds its FSM of behaviours in
:meth:`Agent.build_fsm`. The engine that runs it (services/runtime/engine.py ``Engine``, built
with it: :attr:`Agent.engine`) owns the buffers, the checks against the specification, the
protocol state of its conversations, persistence, liveliness and the threads; an agent's code
reaches it through the context below and, for what few agents need (the transport, the raw
input buffer ``x``, ``send``), through :attr:`Agent.engine`.
"""

from __future__ import annotations

from collections import Counter, deque
from typing import Any, ClassVar

import msgspec

from services.runtime import keys
from services.runtime.behaviour import FSM, Arc, Behaviour, once, periodic
from services.runtime.clock import encode_sim_time
from services.runtime.engine import Engine
from services.runtime.human import (
    FINAL_REPORTS,
    MAX_LINE_CHARS,
    NOTICES_PER_S,
    HumanInput,
    HumanReport,
    ReportKind,
    RequestKind,
)
from services.runtime.person import PersonFace, Told
from services.runtime.roles import Conversation, RoleDecl, Roles
from services.runtime.sources import Sources
from services.runtime.transport import Transport
from services.runtime.values import RESEND_ON_RETURN, Received, SpecViolation
from services.spec.model import SystemSpec

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
the engine calls. Any other of its names that an agent's class defines replaces the context its
code and the engine rely on, or is replaced by it (a helper named ``roles``): ``roco spec
verify-code`` refuses it (services/spec_check/code_check.py). The engine's own names are on
the engine, out of an agent's way."""


class Agent:
    """Base class of every roco agent (a purely computational agent: control subsystem only,
    paper §5.5). Subclasses set ``name`` and implement :meth:`build_fsm`; ``Agent(transport,
    spec)`` builds the agent and its :class:`~services.runtime.engine.Engine` (raises SpecError
    for a name not in ``spec``, RoleMismatch for roles that differ from its interface)."""

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
        engine = Engine(self, transport, spec)
        self.engine = engine
        """The engine that runs this agent (services/runtime/engine.py): its transport,
        specification, raw buffers ``x``/``y``, ``send``/``reply``, ``stop``, ``state``."""
        self.log = engine.log
        self.counters: Counter[str] = engine.counters
        """The agent's counters (``roco status``), shared with its engine."""
        self.peers: set[str] = engine.peers
        """Agents whose liveliness token is present (kept up to date on the agent's thread)."""
        self.r: deque[Any] = engine.r
        """The receptor input buffer: the events :meth:`post` put (paper §3.2)."""
        self.roles: Roles = engine.roles
        """The agent's protocol roles and their open conversations (services/runtime/roles/)."""
        self.note: Any = self.NOTE() if self.NOTE is not None else None
        """The agent's :attr:`NOTE`, kept across a restart by the runtime (None: none)."""
        if type(self).persist is Agent.persist:  # the engine keeps without calling in here
            engine.persist = engine.keep
        engine.start()

    @property
    def sources(self) -> Sources:
        """The agent's clocks, random bytes and fresh identifiers (services/runtime/sources.py):
        the transport's ``sources`` if it offers them (a replay's), else the system's."""
        return self.engine.sources

    @sources.setter
    def sources(self, sources: Sources) -> None:
        self.engine.sources = sources

    # ---- to be provided by agents -------------------------------------------------------
    def build_fsm(self) -> FSM:
        """The agent's FSM of behaviours (paper §3.2). Called once, when the agent is built."""
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
        changed (``Engine.keep``). An agent whose data of a kept conversation follows from its
        state sets it here before calling this (a_ta: the leaf step it is in). Raises OSError
        when the state folder cannot be written."""
        self.engine.keep()

    def on_restored(self, conversation: Conversation) -> None:
        """A conversation of a role declared with ``keep``, taken back after a restart (when
        the agent is built, before :meth:`setup`): in its protocol state, with its
        :attr:`~services.runtime.roles.Conversation.data` (docs/recovery.md). The agent
        rebuilds what it holds of it here. Raising TypeError or ValueError (e.g. the opening
        carries content of another type: ``conversation.opening_content(kind)``) drops it."""

    # ---- the context of the agent's code --------------------------------------------------
    def post(self, event: Any) -> None:
        """Put a receptor event into :attr:`r` (any thread; wakes a waiting behaviour)."""
        self.engine.post(event)

    def emit(self, key: str, payload: bytes) -> None:
        """Put a payload for one of the agent's effectors (a non-FIPA key, e.g. a_hi's
        ``roco/human/out``), or an already encoded communicate sent again as it was, into the
        output buffer (sent after this step)."""
        self.engine.y.append((key, payload))

    def handle_received(self) -> None:
        """Route every communicate in the input buffer ``x`` to its protocol role and the
        agent's handler (services/runtime/roles/), oldest first."""
        x, take = self.engine.x, self.roles.take
        while x:
            take(x.popleft())
