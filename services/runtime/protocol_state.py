"""The protocol state of every conversation: FIPA's rules on a conversation, in one place;
and the ontology a communicate's content language needs.

Every communicate sent or received must belong to its conversation (FIPA SC00026–SC00036,
SC00037 §3.12, SC00061; the application's protocols, e.g. the paper's coordinate, §5.4, as the
specification declares them). :func:`judge` decides it, the one home of those rules (see its
docstring), for the agents' runtime, ``roco spec verify``, the coverage of the specification,
the gateway and the ROS 2 face; :func:`follow` is the same, raising its refusal.
:class:`CrossingTracker` follows one conversation through its protocol's state machine
(:class:`shared.fipa_codec.protocols.Protocol`) while placing communicates that crossed on the
wire; :class:`ProtocolStates` holds one tracker per peer and conversation-id for an agent, in
bounded memory. A communicate in a content language must name that language's ontology
(:func:`expected_ontology`).

The conversations themselves, as an agent's roles take part in them, are
:class:`services.runtime.roles.Conversation`; the replies an agent awaits, with their reply-by
deadlines and retransmissions, are services/runtime/replies.py.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Final, Literal, NoReturn

from shared.fipa_codec.acts import Performative
from shared.fipa_codec.languages import load_all
from shared.fipa_codec.protocols import (
    INITIATOR,
    PARTICIPANT,
    PROTOCOLS,
    Protocol,
    ProtocolViolation,
    Role,
)

ONTOLOGY = "O_RoCo"
"""The Robot Companion's ontology of the robot's environment (paper §5.4), named by every content
language but L_EX, and expected of a language roco does not know."""


def expected_ontology(language: str) -> str:
    """The ontology a communicate in content language ``language`` must name (FIPA SC00061
    §2.3: the ``ontology`` parameter gives meaning to the content's symbols): the one the
    language names (shared/fipa_codec/languages: O_RoCo for all but L_EX, whose robot frames
    and joints are O_Velma's), or O_RoCo for a language roco does not know."""
    known = load_all().get(language)
    return known.ontology if known is not None else ONTOLOGY


# ---------------------------------------------------------------------------------------------
# Protocol state per conversation ("at run time": the performative must be allowed in
# the conversation's current protocol state), tolerant of communicates crossing on the wire.

Step = tuple[Role, Performative, bool | None]
"""One communicate as the protocol sees it: (sender's role, performative, terminal), where
``terminal`` says whether an ``inform`` reports a terminal L_SW state (None: not known, either
reading is tried)."""

FORGOTTEN = "unknown"
"""The state of a conversation the tracker never saw begin, entered by a ``cancel`` for it
(the cancel of a conversation that ended long ago, or before a restart)."""

_CANCEL_ENDS = frozenset({"cancelled", "cancel-failed", "not-understood"})
"""Final states a late cancel cannot follow: the conversation already ended by a cancel or by
not-understood."""


class ConversationError(ValueError):
    """A communicate that cannot belong to the conversation it names (another protocol)."""


@dataclass(frozen=True)
class Position:
    """Where a reading of a conversation stands: the protocol ``state``; ``owed`` True
    while a late cancel waits for the participant's answer; ``resume`` the state a pending
    ``cancel`` left, where the conversation goes on if the participant fails to cancel."""

    state: str
    owed: bool = False
    resume: str | None = None


@dataclass(frozen=True)
class Reading:
    """One order of a conversation's communicates that its protocol allows.

    Communicates of the two parties may cross on the wire: a party sends before it has seen
    what the other sent. A reading keeps the settled prefix as a :class:`Position` (``base``)
    and the trailing ``run`` of communicates from one side (``side``) that the other side
    may not have seen when it sent its next communicate; that next communicate may be placed
    before any suffix of the run. The run's ``terminal`` flags are resolved."""

    base: Position
    side: Role | None = None
    run: tuple[Step, ...] = ()
    tip: tuple[Position, ...] | None = field(default=None, compare=False, repr=False)
    """The positions after ``run`` from ``base`` (a cache: None until first needed; a pure
    function of ``base`` and ``run`` under the tracker's protocol, so a stream of one side's
    communicates advances from it in O(1) instead of replaying the run each time)."""


_STEPS: dict[tuple[object, ...], tuple[Protocol, tuple[Reading, ...], tuple[Reading, ...], bool, bool]] = {}
"""Memo of :meth:`CrossingTracker._found` and of whether every reading it gives has ended,
keyed by (readings id, role, performative, terminal, own, seen, max_run, max_readings); the
protocol and the readings are kept in the value, so an id reused after either was freed never
matches, nor do the same readings followed under another protocol (readings are held once by
value, :data:`_READINGS`: equal readings are one object, and the key need not hash them).
Conversations repeat the same few readings (every fipa-request goes start → requested → done;
a stream of informs keeps the same run), so following a communicate is a dict look-up instead
of replaying its readings (≈ 20 µs → ≈ 2 µs; roco bench, docs/benchmarks.md)."""
_STEPS_MAX = 8192
"""Entries of :data:`_STEPS` kept before it is emptied (bounded memory)."""
_READINGS: dict[tuple[int, tuple[Reading, ...]], tuple[Protocol, tuple[Reading, ...]]] = {}
"""Every tuple of readings :data:`_STEPS` gives, by protocol (id, the protocol kept in the
value) and value: one computed again is replaced by the one held, so that equal readings are one
object and the memo is keyed by its id (emptied with :data:`_STEPS`). Per protocol, because a
reading caches its tip, which depends on the protocol: fipa-request and coordinate share the
reading "requested, then the participant's inform", which ends the one and not the other."""


def _held(protocol: Protocol, readings: tuple[Reading, ...]) -> tuple[Reading, ...]:
    """The one object equal to ``readings`` under ``protocol`` (see :data:`_READINGS`)."""
    key = (id(protocol), readings)
    held = _READINGS.get(key)
    if held is None or held[0] is not protocol:
        held = (protocol, readings)
        _READINGS[key] = held
    return held[1]


_INITIAL: dict[int, tuple[Protocol, tuple[Reading, ...]]] = {}
"""Per protocol (by id, the protocol kept as in :data:`_STEPS`), the readings of a conversation
that has not begun: built once, shared by every new tracker (readings are immutable)."""


def _initial(protocol: Protocol) -> tuple[Reading, ...]:
    held = _INITIAL.get(id(protocol))
    if held is None or held[0] is not protocol:
        readings = (Reading(Position(protocol.initial)),)
        held = (protocol, _held(protocol, readings))
        _INITIAL[id(protocol)] = held
    return held[1]


class CrossingTracker:
    """Follows one conversation through ``protocol`` (a state machine, or the name of one of
    FIPA's library, :data:`~shared.fipa_codec.protocols.PROTOCOLS`), accepting a communicate
    when *some* order of the communicates consistent with the wire allows it.

    Two parties' communicates may cross (FIPA SC00026 §2, SC00027 §2, SC00035 §2: a
    ``cancel`` may cross the participant's outcome, an ``agree`` or a subscription's
    ``inform``). A communicate is accepted when the protocol allows it in arrival order, or
    placed before a suffix of the other side's latest communicates (it was sent before
    those arrived). Each sender's own communicates keep their order. The tracker keeps every
    such reading (up to ``max_readings``) and rejects a communicate only when none allows it.

    The cancel meta-protocol is followed a little further than the state machine does:

    - a ``cancel`` that crossed the participant's outcome arrives after the conversation
      ended (a *late cancel*), or names a conversation the tracker never saw (one that ended
      long ago): the participant may answer it once, with ``inform`` or ``failure``, or not;
    - a ``failure`` answering a ``cancel`` (could not cancel) leaves the conversation going
      on from where the cancel found it, as well as ending it (both readings are kept).

    ``local_role`` is the role of the agent that tracks the conversation (None for an
    observer of the wire, e.g. the traffic recorder). Its own communicates are placed like
    the other side's (its code may act before it reads what already arrived in its input
    buffer), but an own ``cancel`` after the conversation ended is never taken as a late
    cancel: the agent cannot have sent it before the end it caused or received.
    """

    def __init__(
        self,
        protocol: Protocol | str,
        *,
        local_role: Role | None = None,
        max_run: int = 16,
        max_readings: int = 16,
        readings: tuple[Reading, ...] | None = None,
        ended: bool | None = None,
    ) -> None:
        if isinstance(protocol, str):
            if protocol not in PROTOCOLS:
                raise ValueError(f"unknown interaction protocol {protocol!r}; known: {', '.join(PROTOCOLS)}")
            protocol = PROTOCOLS[protocol]
        self.protocol = protocol
        self.local_role = local_role
        self.max_run = max_run
        self.max_readings = max_readings
        self.readings: tuple[Reading, ...] = readings if readings is not None else _initial(protocol)
        """Where the conversation may stand (``readings`` given: a copy's, else its beginning)."""
        self.ended = ended if ended is not None else readings is not None and self._all_ended()
        """Whether every reading has ended (kept with ``readings``, ``ended`` when given with
        them: :attr:`is_finished` asks it of every communicate followed)."""
        self.messages = 0
        self.crossings = 0
        """Communicates accepted only in an order other than their arrival (or as a late
        cancel and its answer)."""
        self.aborted = False
        """True once a not-understood ended the conversation (see :meth:`abort`)."""
        self.aborted_by: Role | None = None
        """Who sent the not-understood that ended the conversation (None: none did)."""
        self.initiator_heard = False
        """The initiator has received a communicate of this conversation (followed or refused)
        since it last sent one: only then may it send a not-understood (FIPA SC00037 §3.12: the
        receiver of a communicate it did not understand)."""
        self.aborted_reply_with: str | None = None
        """The reply-with of the not-understood that ended the conversation: what names it in its
        in-reply-to was sent after it was seen, so cannot have crossed it."""
        self.participant_heard = False
        """The same for the participant."""
        self.opening_reply_with: str | None = None
        """The reply-with of the communicate that opened the conversation (None: it had none,
        or it is not known): the same communicate again, retransmitted, is recognised by it."""
        self.latest_initiator: str | None = None
        """The reply-with of the initiator's latest communicate (None when it had none)."""
        self.latest_participant: str | None = None
        """The reply-with of the participant's latest communicate (None when it had none)."""

    def copy(self) -> CrossingTracker:
        """An independent copy (readings are immutable, so this is cheap)."""
        other = CrossingTracker(
            self.protocol,
            local_role=self.local_role,
            max_run=self.max_run,
            max_readings=self.max_readings,
            readings=self.readings,
            ended=self.ended,
        )  # attribute by attribute: compiled by mypyc (setup.py), the class has no __dict__
        other.messages = self.messages
        other.crossings = self.crossings
        other.aborted = self.aborted
        other.aborted_by = self.aborted_by
        other.aborted_reply_with = self.aborted_reply_with
        other.initiator_heard = self.initiator_heard
        other.participant_heard = self.participant_heard
        other.opening_reply_with = self.opening_reply_with
        other.latest_initiator = self.latest_initiator
        other.latest_participant = self.latest_participant
        return other

    # ---- state -------------------------------------------------------------------------
    @property
    def state(self) -> str:
        """The current state of the first (most in-order) reading."""
        return self._current(self.readings[0]).state

    @property
    def states(self) -> frozenset[str]:
        """The current states of all readings."""
        return frozenset(p.state for p in self._positions())

    def _positions(self) -> list[Position]:
        return [p for r in self.readings for p in self._tip(r)]

    def _ended(self, p: Position) -> bool:
        return (p.state in self.protocol.final or p.state == FORGOTTEN) and not p.owed

    def _all_ended(self) -> bool:
        """Whether every reading has ended (computed; :attr:`ended` keeps it)."""
        return all(self._ended(p) for p in self._positions())

    @property
    def is_finished(self) -> bool:
        """True when every reading has ended (a final state, no cancel waiting for its
        answer), or a not-understood ended the conversation."""
        return self.aborted or self.ended

    @property
    def may_be_finished(self) -> bool:
        """True when some reading has ended (see :attr:`is_finished`)."""
        return self.aborted or any(self._ended(p) for p in self._positions())

    def is_opener(self, role: Role | str, performative: Performative | str) -> bool:
        """True when ``performative`` from ``role`` opens a conversation of this protocol."""
        if role not in (INITIATOR, PARTICIPANT):
            return False
        first = self.protocol.next_state(self.protocol.initial, _role(role), _performative(performative))
        return first is not None

    def abort(self, by: Role | None = None) -> None:
        """A not-understood sent by ``by`` ended the conversation (FIPA SC00037 §3.12): from
        now on only what the other party sent before it saw the not-understood (a communicate
        the protocol allowed where the conversation stood) belongs to it (:func:`follow`)."""
        if not self.aborted:
            self.aborted_by = by
        self.aborted = True

    def heard(self, role: Role | str) -> bool:
        """Whether ``role`` has received a communicate here that it has not answered with
        not-understood (see :attr:`initiator_heard`)."""
        return self.initiator_heard if role == INITIATOR else self.participant_heard

    def hear(self, role: Role | str, heard: bool = True) -> None:
        """``role`` received a communicate of this conversation (``heard`` True), or answered
        what it received with not-understood (False)."""
        if role == INITIATOR:
            self.initiator_heard = heard
        else:
            self.participant_heard = heard

    def forgotten(self) -> None:
        """Begin with a ``cancel`` of a conversation never seen: the participant may answer it
        once (``failure``: nothing to cancel). Only for a tracker that has seen nothing."""
        assert self.messages == 0
        self.readings = (Reading(Position(FORGOTTEN, owed=True)),)
        self.ended = False  # the cancel is owed its answer
        self.messages = 1
        self.crossings = 1

    # ---- advancing ---------------------------------------------------------------------
    def step(
        self,
        role: Role | str,
        performative: Performative | str,
        *,
        terminal: bool | None = False,
        reply_with: str | None = None,
        in_reply_to: str | None = None,
    ) -> str:
        """Record that ``role`` sent ``performative`` (``terminal``: whether an ``inform``
        reports a terminal L_SW state, for a protocol with terminal transitions; None when
        unknown). Returns the new state of the
        first reading. Raises ProtocolViolation (describing the arrival-order reading) when
        no reading allows it; the tracker is then unchanged.

        ``reply_with`` and ``in_reply_to`` are the communicate's parameters (FIPA SC00061
        §2.3): a communicate whose ``in_reply_to`` names the other side's latest
        communicate was sent after that one arrived, so it crossed nothing and is only
        placed after it (e.g. a_co's confirm of a_ta's terminal inform ends the coordinate
        conversation instead of also being read as a confirm sent again before it)."""
        if role not in (INITIATOR, PARTICIPANT):
            raise ValueError(f"role must be 'initiator' or 'participant', not {role!r}")
        self.advance(_role(role), _performative(performative), terminal, reply_with, in_reply_to)
        return self.state

    def advance(
        self,
        role: Role,
        performative: Performative,
        terminal: bool | None,
        reply_with: str | None,
        in_reply_to: str | None,
    ) -> None:
        """:meth:`step` for a ``role`` and a ``performative`` known to be valid (a member of
        each), without the state it returns: what :func:`follow` calls for every communicate
        an agent sends and receives. Raises ProtocolViolation as :meth:`step` does."""
        s: Step = (role, performative, terminal)
        own = self.local_role is not None and role == self.local_role
        other = self.latest_participant if role == INITIATOR else self.latest_initiator
        seen = in_reply_to is not None and in_reply_to == other
        readings = self.readings
        key = (id(readings), role, performative, terminal, own, seen, self.max_run, self.max_readings)
        cached = _STEPS.get(key)
        if cached is None or cached[0] is not self.protocol or cached[1] is not readings:
            cached = self._remember(key, s, own, seen)
        found = cached[2]
        if not found:
            self._violation(s)
        self.readings = found
        self.ended = cached[4]
        self.messages += 1
        if not cached[3]:
            self.crossings += 1
        if role == INITIATOR:
            self.latest_initiator = reply_with
        else:
            self.latest_participant = reply_with

    def _remember(
        self, key: tuple[object, ...], s: Step, own: bool, seen: bool
    ) -> tuple[Protocol, tuple[Reading, ...], tuple[Reading, ...], bool, bool]:
        """:meth:`_found` for ``s`` from the current readings, with whether every reading
        it gives has ended, kept in :data:`_STEPS` under ``key``."""
        found, in_order = self._found(s, own, seen)
        if len(_STEPS) >= _STEPS_MAX:
            _STEPS.clear()
            _READINGS.clear()
            _INITIAL.clear()
        found = _held(self.protocol, found)
        ended = bool(found) and all(self._ended(p) for r in found for p in self._tip(r))
        entry = (self.protocol, self.readings, found, in_order, ended)
        _STEPS[key] = entry
        return entry

    def _violation(self, s: Step) -> NoReturn:
        """Raise the ProtocolViolation of ``s``, which no reading allows."""
        state = self.state
        raise ProtocolViolation(
            self.protocol.name,
            state,
            s[0],
            s[1],
            self.protocol.allowed(state) if state in self.protocol.states else [],
            finished=state in self.protocol.final or state == FORGOTTEN,
        )

    def _found(self, s: Step, own: bool, seen: bool = False) -> tuple[tuple[Reading, ...], bool]:
        """The readings after ``s`` (at most ``max_readings``; empty when none allows it) and
        whether some reading took it in arrival order under the plain protocol. A pure
        function of the protocol, ``max_run``, ``max_readings``, the readings, ``s``, ``own``
        and ``seen``: :meth:`step` keeps its results in :data:`_STEPS`."""
        found: list[Reading] = []
        in_order = False
        for reading in self.readings:
            for candidate, plain in self._extend(reading, s, own, seen):
                in_order = in_order or plain
                if candidate not in found:
                    found.append(candidate)
        return tuple(found[: self.max_readings]), in_order

    def _extend(self, r: Reading, s: Step, own: bool, seen: bool = False) -> list[tuple[Reading, bool]]:
        """The readings after ``s`` joins ``r``, each with True when ``s`` was appended in
        arrival order under the plain protocol; ``seen``: ``s`` answers the other side's
        latest communicate, so it is placed after the whole run."""
        out: list[tuple[Reading, bool]] = []
        if r.side is None or r.side == s[0] or not r.run:
            # same side as the run (or none): s follows the run, as each sender's own
            # communicates arrive in the order they were sent
            tip = self._tip(r)
            for cur in tip:
                for _, done, plain in self._advance(cur, s, late_ok=not own and not seen, crossing=not seen):
                    after = self._after(tip, done)
                    out.append((self._trim(Reading(r.base, s[0], (*r.run, done), after)), plain))
            return out
        # s is from the other side: it may have been sent before any suffix of the run arrived
        for i in range(len(r.run), len(r.run) - 1 if seen else -1, -1):
            for before in self._replay(r.base, r.run[:i]):
                for nxt, done, plain in self._advance(
                    before, s, late_ok=not own and not seen, crossing=not seen
                ):
                    if i == len(r.run):
                        out.append((Reading(before, s[0], (done,)), plain))
                    elif self._replay(nxt, r.run[i:]):
                        out.append((Reading(nxt, r.side, r.run[i:]), False))
        return out

    def _advance(
        self, at: Position, s: Step, *, late_ok: bool, crossing: bool = True
    ) -> list[tuple[Position, Step, bool]]:
        """The ways ``s`` may follow ``at``: each the next position, ``s`` with its
        ``terminal`` flag resolved, and True when the plain protocol allows it (False for a
        late cancel, its answer, or a failed cancel resuming the conversation); ``crossing``:
        ``s`` may have crossed the other party's latest on the wire, so the protocol's
        crossing transitions are open to it."""
        role, perf, terminal = s
        out: list[tuple[Position, Step, bool]] = []
        for flag in (False, True) if terminal is None else (terminal,):
            nxt = self.protocol.next_state(at.state, role, perf, flag)
            plain = nxt is not None
            went: str | None = None
            if nxt is None and crossing:
                if at.state == "cancelling" and at.resume is not None:
                    # the participant's communicate sent before the cancel arrived: what the
                    # state the cancel found allows (not what any cancellable state would)
                    went = (
                        self.protocol.next_state(at.resume, role, perf, flag) if role == PARTICIPANT else None
                    )
                    if went is not None:
                        nxt = went if went in self.protocol.final else "cancelling"
                else:
                    nxt = self.protocol.crossing_transitions.get((at.state, role, perf))
            if nxt is None or any(p.state == nxt for p, _, _ in out):
                continue
            resume = at.resume
            if nxt == "cancelling" and at.state != "cancelling":
                resume = at.state
            elif nxt == "cancelling" and went is not None:
                resume = went  # the conversation the cancel found has moved on
            elif nxt != "cancelling":
                resume = None
            out.append((Position(nxt, at.owed, resume), (role, perf, flag), plain))
            if nxt == "cancel-failed" and at.resume is not None:
                # could not cancel: the conversation goes on where the cancel found it
                out.append((Position(at.resume, at.owed), (role, perf, flag), plain))
        if out:
            return out
        done: Step = (role, perf, bool(terminal))
        if at.owed and role == PARTICIPANT and perf in (Performative.INFORM, Performative.FAILURE):
            return [(Position(at.state), done, False)]  # the answer to a late cancel
        if (
            late_ok
            and not at.owed
            and role == INITIATOR
            and perf is Performative.CANCEL
            and at.state in self.protocol.final
            and at.state not in _CANCEL_ENDS
            and "cancelling" in self.protocol.states
        ):
            return [(Position(at.state, owed=True), done, False)]  # a cancel that crossed the outcome
        return []

    def _replay(self, at: Position, steps: tuple[Step, ...]) -> list[Position]:
        """The positions after ``steps`` (``terminal`` flags resolved) from ``at``; empty
        when the protocol does not allow them."""
        positions = [at]
        for s in steps:
            positions = list(
                dict.fromkeys(p for q in positions for p, _, _ in self._advance(q, s, late_ok=True))
            )
            if not positions:
                break
        return positions

    def _tip(self, r: Reading) -> tuple[Position, ...]:
        """The positions after ``r``'s run (cached in ``r``)."""
        if r.tip is None:
            object.__setattr__(r, "tip", tuple(self._replay(r.base, r.run)))
        assert r.tip is not None
        return r.tip

    def _after(self, tip: tuple[Position, ...], s: Step) -> tuple[Position, ...]:
        """The positions after one more step ``s`` from ``tip`` (as :meth:`_replay`)."""
        return tuple(dict.fromkeys(p for q in tip for p, _, _ in self._advance(q, s, late_ok=True)))

    def _current(self, r: Reading) -> Position:
        positions = self._tip(r)
        return positions[0] if positions else r.base

    def _trim(self, r: Reading) -> Reading:
        """Settle the oldest communicates of a run longer than ``max_run`` (bounded memory:
        a crossing over more than ``max_run`` communicates is not tolerated)."""
        if len(r.run) <= self.max_run:
            return r
        cut = len(r.run) - self.max_run
        settled = self._replay(r.base, r.run[:cut])
        if not settled:
            return r
        # one settled position leads to the same positions after the rest of the run
        return Reading(settled[0], r.side, r.run[cut:], r.tip if len(settled) == 1 else None)


def _role(role: str) -> Role:
    return INITIATOR if role == INITIATOR else PARTICIPANT


def _performative(performative: Performative | str) -> Performative:
    """The member itself, else the member of that value (ValueError for an unknown one): a
    member passes without the enum's call (≈ 0.5 µs, once per communicate sent and received)."""
    return performative if isinstance(performative, Performative) else Performative(performative)


_CANCEL: Final = Performative.CANCEL
_NOT_UNDERSTOOD: Final = Performative.NOT_UNDERSTOOD
"""Members asked of every communicate followed, looked up once (a member's lookup on its enum
class is a Python call on CPython 3.11)."""

Outcome = Literal["step", "crossing", "forgotten", "aborted", "copy"]
"""What :func:`follow` did with a communicate."""

Refusal = ProtocolViolation | ConversationError
"""Why a communicate has no place in its conversation (:func:`judge`)."""


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


def judge(
    tracker: CrossingTracker | None,
    protocol: Protocol | str,
    role: Role,
    performative: Performative,
    *,
    terminal: bool | None = False,
    local_role: Role | None = None,
    reply_with: str | None = None,
    in_reply_to: str | None = None,
    copies: bool = True,
) -> tuple[CrossingTracker, Outcome | None, Refusal | None]:
    """Judge one communicate of ``protocol`` (a state machine: the specification's,
    services/spec/protocol_defs.py ``machine_of``; or the name of one of FIPA's library,
    :data:`~shared.fipa_codec.protocols.PROTOCOLS`) sent by ``role`` in the conversation
    ``tracker`` follows (None: one not seen before). The one home of FIPA's rules on a
    conversation (SC00026–SC00036 "Exceptions to IP Flow", SC00061 conversation-id), used by
    the runtime (:class:`ProtocolStates`), ``roco spec verify``, the coverage of the
    specification and the ROS 2 face:

    - a communicate must be allowed where the conversation stands, allowing for what crossed
      on the wire (:class:`CrossingTracker`); after the conversation's end nothing more
      belongs to it, whoever sends it (but a cancel that crossed the end, and its answer);
    - an opening communicate in a conversation already open or ended is refused: a
      conversation-id names one conversation (SC00061); a new one needs a new id (a
      byte-identical copy, a retransmission, is filtered before: services/runtime/dedup.py,
      :attr:`services.report.load.Message.copy_of`);
    - ``not-understood`` comes only from the receiver of a communicate of the conversation
      (one received since it last sent anything there; SC00037 §3.12) and ends the
      conversation; after it, only what the other party sent before it saw the not-understood
      belongs to it (not what names it in its in-reply-to);
    - a communicate of another protocol than the conversation's is refused
      (:class:`ConversationError`);
    - a ``cancel`` received for a conversation never seen (it ended long ago, or before a
      restart) is taken (``forgotten``): the participant may answer it with ``failure``; an
      agent takes a ``not-understood`` of a conversation it does not know so too (an observer,
      ``local_role`` None, which sees the whole record, does not);
    - with ``copies``, the opening communicate again, recognised by its reply-with (FIPA
      SC00061 §2.4), is a retransmission (``copy``: not followed again): what an agent that
      restarted, and lost the bytes it had seen, receives; ``roco spec verify``, which has the
      bytes, judges a copy by them and passes False.

    Returns the conversation's tracker (new when ``tracker`` is None; changed in place
    otherwise), the outcome (``step``: allowed in arrival order; ``crossing``: allowed only
    as crossing a communicate on the wire; ``forgotten``; ``aborted``: a not-understood that
    ended the conversation) and None; or the tracker, None and the refusal, the tracker then
    unchanged but for noting that the receiver heard something it may answer with
    not-understood. Raises ValueError for an unknown protocol name or role."""
    if role != INITIATOR and role != PARTICIPANT:
        raise ValueError(f"role must be 'initiator' or 'participant', not {role!r}")
    unknown = tracker is None
    if tracker is None:
        tracker = CrossingTracker(protocol, local_role=local_role)
        if performative is _CANCEL and role == INITIATOR and local_role != INITIATOR:
            tracker.forgotten()
            tracker.latest_initiator = reply_with
            tracker.hear(PARTICIPANT)
            return tracker, "forgotten", None
    if performative is _NOT_UNDERSTOOD:
        if unknown and local_role is not None and role != local_role:
            tracker.abort(role)  # of a conversation this agent no longer knows (ended and forgotten)
            return tracker, "aborted", None
        if not tracker.heard(role):
            return (
                tracker,
                None,
                ProtocolViolation(
                    tracker.protocol.name,
                    "not-understood" if tracker.aborted else tracker.state,
                    role,
                    performative,
                    [],
                    note=(
                        f"the {role} has received nothing in this conversation since it last sent "
                        "something: not-understood answers a communicate received (FIPA SC00037 §3.12)"
                    ),
                ),
            )
        tracker.hear(role, False)
        if not tracker.aborted:
            tracker.aborted_reply_with = reply_with
        tracker.abort(role)
        return tracker, "aborted", None
    name = protocol if isinstance(protocol, str) else protocol.name
    if tracker.protocol is not protocol and tracker.protocol.name != name:
        tracker.hear(_other(role))
        tracker.hear(role, False)
        return (
            tracker,
            None,
            ConversationError(
                f"the conversation follows {tracker.protocol.name}, not {name}; a conversation-id names "
                f"one conversation (FIPA SC00061): a {name} conversation needs an id of its own"
            ),
        )
    if (
        copies
        and reply_with
        and reply_with == tracker.opening_reply_with
        and role == INITIATOR
        and _opens(tracker.protocol, role, performative)
    ):
        return tracker, "copy", None
    opening = tracker.messages == 0
    crossings = tracker.crossings
    try:
        if tracker.aborted and (
            role == tracker.aborted_by
            or (in_reply_to is not None and in_reply_to == tracker.aborted_reply_with)
        ):  # its sender saw the not-understood that ended the conversation
            raise ProtocolViolation(
                tracker.protocol.name,
                "not-understood",
                role,
                performative,
                [],
                finished=True,
            )
        tracker.advance(role, _performative(performative), terminal, reply_with, in_reply_to)
    except ProtocolViolation as exc:
        tracker.hear(_other(role))
        tracker.hear(role, False)
        if _opens(tracker.protocol, role, performative) and tracker.messages > 0:
            return (
                tracker,
                None,
                ProtocolViolation(
                    exc.protocol,
                    exc.state,
                    role,
                    performative,
                    exc.allowed,
                    finished=tracker.is_finished,
                    note=(
                        f"{performative.value} opens a conversation, and conversation-id names one "
                        "conversation (FIPA SC00061): a new conversation needs a new conversation-id"
                    ),
                ),
            )
        return tracker, None, exc
    tracker.hear(_other(role))
    tracker.hear(role, False)
    if opening:
        tracker.opening_reply_with = reply_with
    if tracker.aborted:  # sent before the other party's not-understood arrived
        tracker.crossings += 1
        return tracker, "crossing", None
    return tracker, "crossing" if tracker.crossings > crossings else "step", None


def follow(
    tracker: CrossingTracker | None,
    protocol: Protocol | str,
    role: Role,
    performative: Performative,
    *,
    terminal: bool | None = False,
    local_role: Role | None = None,
    reply_with: str | None = None,
    in_reply_to: str | None = None,
    copies: bool = True,
) -> tuple[CrossingTracker, Outcome]:
    """Advance a conversation by one communicate as :func:`judge` rules (the same arguments
    and outcomes); raises its refusal instead of returning it: ProtocolViolation when the
    communicate is not allowed where the conversation stands, ConversationError when the
    conversation follows another protocol. ``tracker`` is changed in place."""
    tracker, outcome, refusal = judge(
        tracker,
        protocol,
        role,
        performative,
        terminal=terminal,
        local_role=local_role,
        reply_with=reply_with,
        in_reply_to=in_reply_to,
        copies=copies,
    )
    if refusal is not None:
        raise refusal
    assert outcome is not None
    return tracker, outcome


def _machine(protocol: Protocol | str) -> Protocol:
    """The state machine of ``protocol``; raises ValueError for an unknown name."""
    known = PROTOCOLS.get(protocol) if isinstance(protocol, str) else protocol
    return known if known is not None else CrossingTracker(protocol).protocol


def _opens(protocol: Protocol | str, role: Role, performative: Performative) -> bool:
    """True when ``performative`` from ``role`` opens a conversation of ``protocol`` (as
    :meth:`CrossingTracker.is_opener`, without building a tracker)."""
    machine = _machine(protocol)
    if role not in (INITIATOR, PARTICIPANT):
        return False
    return machine.next_state(machine.initial, _role(role), _performative(performative)) is not None


ConversationKey = tuple[str, str]
"""(peer, conversation-id)."""


class ProtocolStates:
    """The protocol state of every conversation one agent takes part in, one
    :class:`CrossingTracker` per (peer, conversation-id), for what it sends and receives.

    Bounded memory: finished conversations (final state, or ended by not-understood) are
    kept, the newest ``max_ended`` of them, for communicates that crossed their end on the
    wire; open ones beyond ``max_open`` are forgotten oldest first. A forgotten
    conversation starts again from its protocol's initial state.

    Changes made during one elementary action can be undone (:meth:`rollback`) when the
    transition function fails and its output buffer is dropped; :meth:`commit` keeps them.
    """

    def __init__(self, max_open: int = 1024, max_ended: int = 512) -> None:
        self.max_open = max_open
        self.max_ended = max_ended
        self._open: OrderedDict[ConversationKey, CrossingTracker] = OrderedDict()
        self._ended: OrderedDict[ConversationKey, CrossingTracker] = OrderedDict()
        self._undo: dict[ConversationKey, CrossingTracker | None] = {}
        self._open_per_peer: dict[str, int] = {}
        self.forgotten_open = 0
        """Open conversations forgotten because more than ``max_open`` were open."""

    def get(self, peer: str, conversation_id: str) -> CrossingTracker | None:
        """The tracker of a conversation, or None when unknown or forgotten."""
        key = (peer, conversation_id)
        return self._open.get(key) or self._ended.get(key)

    def observe(
        self,
        peer: str,
        conversation_id: str,
        protocol: Protocol | str,
        role: Role,
        performative: Performative,
        *,
        local_role: Role,
        terminal: bool | None = False,
        reply_with: str | None = None,
        in_reply_to: str | None = None,
    ) -> Outcome:
        """Follow one communicate sent by ``role`` (the agent's own when ``role ==
        local_role``) in conversation ``conversation_id`` with ``peer``; see :func:`follow`
        for the outcome and the exceptions (the table is unchanged when one is raised);
        ``reply_with`` and ``in_reply_to`` as in :meth:`CrossingTracker.step`."""
        key = (peer, conversation_id)
        old = self._open.get(key) or self._ended.get(key)
        # a tracker already stepped since the last commit is a copy no undo holds: stepped in
        # place (the communicates of one stream taken in together copy it once)
        work = old if key in self._undo or old is None else old.copy()
        tracker, outcome, refusal = judge(
            work,
            protocol,
            role,
            performative,
            terminal=terminal,
            local_role=local_role,
            reply_with=reply_with,
            in_reply_to=in_reply_to,
        )
        if refusal is not None and old is None:
            raise refusal  # no such conversation: the table stays without it
        if key not in self._undo:
            self._undo[key] = old
        self._put(key, tracker)  # refused: only that its receiver heard it is kept
        if refusal is not None:
            raise refusal
        assert outcome is not None
        return outcome

    def _put(self, key: ConversationKey, tracker: CrossingTracker) -> None:
        if tracker.is_finished:
            self._drop(key)
            self._ended[key] = tracker
            while len(self._ended) > self.max_ended:
                self._ended.popitem(last=False)
        elif key in self._open:  # still open: the newest now (its peer's count stays)
            self._open[key] = tracker
            self._open.move_to_end(key)
        else:
            self._ended.pop(key, None)
            self._open[key] = tracker
            self._open_per_peer[key[0]] = self._open_per_peer.get(key[0], 0) + 1
            while len(self._open) > self.max_open:
                oldest, _ = self._open.popitem(last=False)
                self._count_closed(oldest[0])
                self.forgotten_open += 1

    def _drop(self, key: ConversationKey) -> None:
        """Remove a conversation from both tables (keeping the per-peer count right)."""
        if self._open.pop(key, None) is not None:
            self._count_closed(key[0])
        self._ended.pop(key, None)

    def _count_closed(self, peer: str) -> None:
        n = self._open_per_peer.get(peer, 0) - 1
        if n > 0:
            self._open_per_peer[peer] = n
        else:
            self._open_per_peer.pop(peer, None)

    def open_with(self, peer: str) -> int:
        """Open (not yet finished) conversations with ``peer``, either side having opened them
        (O(1); the bound of services/runtime/limits.py is checked against it)."""
        return self._open_per_peer.get(peer, 0)

    def commit(self) -> None:
        """Keep the changes since the last commit (the output buffer was dispatched)."""
        self._undo.clear()

    def rollback(self) -> None:
        """Undo the changes since the last commit (the output buffer was dropped)."""
        for key, old in self._undo.items():
            self._drop(key)
            if old is not None:
                self._put(key, old)
        self._undo.clear()

    def __len__(self) -> int:
        return len(self._open) + len(self._ended)

    @property
    def open_count(self) -> int:
        """Conversations not yet finished."""
        return len(self._open)
