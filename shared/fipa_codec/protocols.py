"""FIPA interaction protocols (FIPA SC00025 library) as checkable finite state machines.

A :class:`Protocol` is data: states, an initial state, final states and a transition table
``(state, role, performative) -> state``, where ``role`` is ``"initiator"`` (the agent that
sent the first message) or ``"participant"``. The rules of following one conversation (one
``conversation-id`` between one initiator and one participant) through it have one home,
services/runtime/protocol_state.py (``judge``, ``follow``, ``CrossingTracker``: the agents'
runtime and ``roco spec verify`` follow conversations with them), which raises
:class:`ProtocolViolation` on a message the conversation does not allow.

Conventions shared by all protocols (each after the FIPA specification cited):

* ``not-understood`` (FIPA SC00037 §3.12): the machine has it from both roles in every
  state after the first message that is not final, leading to the final state
  ``not-understood``; a protocol with no such state (a *one-message* protocol: the
  initiator's ``inform`` ends it) has no state ``not-understood``. Following a conversation
  (``judge`` in services/runtime/protocol_state.py, where the rules of following live), a
  not-understood comes only from the receiver of a communicate of the conversation that it
  has not yet answered with not-understood, also one answering the message that ended the
  conversation (a malformed final ``inform``, the one message of a one-message protocol);
  it ends the conversation, after which only what the other party sent before it saw the
  not-understood belongs to it.
* The *cancel meta-protocol* (SC00026 §2, SC00027 §2, SC00028 §2, SC00029 §2, SC00030 §2,
  SC00033 §2, SC00034 §2, SC00035 §2):
  where a protocol allows it, the initiator may send ``cancel`` while the participant owes
  it an outcome; the participant answers ``inform`` (cancelled) or ``failure`` (could not
  cancel), both ending the conversation (states ``cancelled``/``cancel-failed``). What the
  participant sent before the ``cancel`` arrived takes a crossing transition
  (:attr:`Protocol.crossing_transitions`) in state ``cancelling``: an ``agree`` (a
  ``propose``) leaves it cancelling, a final answer (``refuse``, ``inform-ref`` …) ends the
  conversation as it would have.
* FIPA's ``inform-done``/``inform-result``/``inform-t/f`` are all the performative
  ``inform``.

The library, by the FIPA ``protocol`` parameter name (:data:`PROTOCOLS`), is FIPA's: the
eleven protocols of the FIPA SC00025 library, ``fipa-request`` (SC00026) to ``fipa-propose``
(SC00036), each after its specification. The application's own protocols (the paper's
``coordinate``, §5.4 Figure 8) are declared in its specification
(services/spec/robot_companion.toml) and built by services/spec/protocol_defs.py with the
same builder, :func:`_build`; this module holds none of them.

A one-to-many protocol (the contract nets, the auctions, brokering and recruiting, where the
initiator addresses several participants) is modelled, like the others, as the conversation
between the initiator and one participant: one tracker per participant. Where the initiator
goes on without waiting for the participant (an auction's next price, or its end), a
crossing transition takes a bid that crossed it on the wire.

A protocol may tell apart an ``inform`` that reports a terminal L_SW state (Succeeded,
Error, Preempted, Replan) from one that reports any other state, as the specification's
``coordinate`` does (paper §5.4); the transition table then has a second part,
``terminal_transitions``, taken by an ``inform`` flagged terminal (:meth:`Protocol.next_state`
with ``terminal=True``; :func:`is_terminal_report` works the flag out from a communicate's
content). None of FIPA's protocols has any.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Final, Literal

from shared.fipa_codec.acts import Performative
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.message import Communicate

__all__ = [
    "INITIATOR",
    "PARTICIPANT",
    "PROTOCOLS",
    "Protocol",
    "ProtocolViolation",
    "Role",
    "is_terminal_report",
]

Role = Literal["initiator", "participant"]
INITIATOR: Final = "initiator"
PARTICIPANT: Final = "participant"
_ROLES: tuple[Role, Role] = (INITIATOR, PARTICIPANT)
_ABBREV = {INITIATOR: "I", PARTICIPANT: "P"}

Key = tuple[str, Role, Performative]
"""A transition's trigger: (state, role of the sender, performative)."""


@dataclass(frozen=True, eq=False)
class Protocol:
    """An interaction protocol as a finite state machine (FIPA SC00025 §2 IP library).

    ``transitions`` maps (state, sender's role, performative) to the next state;
    ``terminal_transitions`` the same for an ``inform`` flagged ``terminal=True`` (none of
    FIPA's protocols has any; the specification's ``coordinate`` has). ``spec`` names the
    FIPA specification (or the paper section). The machine is checked on construction: the
    initial and final states are states, no transition leaves a final state, every state is
    reachable from ``initial`` and can reach a final state; ValueError otherwise.
    """

    name: str
    states: frozenset[str]
    initial: str
    final: frozenset[str]
    transitions: Mapping[Key, str]
    terminal_transitions: Mapping[Key, str] = field(default_factory=dict)
    spec: str = ""
    description: str = ""
    crossing_transitions: Mapping[Key, str] = field(default_factory=dict)
    """Transitions taken only by a communicate sent before its sender saw the other party's
    latest (the two crossed on the wire): e.g. the participant's ``agree`` arriving after the
    initiator's ``cancel``. A party's own view of the conversation needs them (the deadlock
    explorer's role automata); a follower that can reorder what crossed
    (services/runtime/protocol_state.py) takes them only for a communicate that does not
    name the other party's latest in its in-reply-to."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "transitions", MappingProxyType(dict(self.transitions)))
        object.__setattr__(self, "terminal_transitions", MappingProxyType(dict(self.terminal_transitions)))
        object.__setattr__(self, "crossing_transitions", MappingProxyType(dict(self.crossing_transitions)))
        problems = self._problems()
        if problems:
            raise ValueError(f"protocol {self.name}: " + "; ".join(problems))

    def _edges(self) -> Iterable[tuple[Key, str, bool]]:
        for key, target in self.transitions.items():
            yield key, target, False
        for key, target in self.terminal_transitions.items():
            yield key, target, True

    def _problems(self) -> list[str]:
        problems = []
        if self.initial not in self.states:
            problems.append(f"initial state {self.initial!r} is not a state")
        if self.initial in self.final:
            problems.append("the initial state is final")
        problems += [f"final state {s!r} is not a state" for s in sorted(self.final - self.states)]
        successors: dict[str, set[str]] = {s: set() for s in self.states}
        for (source, role, performative), target, _ in self._edges():
            if role not in _ROLES:
                problems.append(f"unknown role {role!r}")
            if not isinstance(performative, Performative):
                problems.append(f"{performative!r} is not a Performative")
            for s in (source, target):
                if s not in self.states:
                    problems.append(f"transition uses unknown state {s!r}")
            if source in self.final:
                problems.append(f"transition leaves final state {source!r}")
            if source in successors and target in self.states:
                successors[source].add(target)
        for (source, role, performative), target in self.crossing_transitions.items():
            if (source, role, performative) in self.transitions:
                problems.append(
                    f"crossing transition {(source, role, performative.value)} is also a transition"
                )
            for s in (source, target):
                if s not in self.states:
                    problems.append(f"crossing transition uses unknown state {s!r}")
            if source in self.final:
                problems.append(f"crossing transition leaves final state {source!r}")
        if problems:
            return problems
        reached = _closure({self.initial}, successors)
        problems += [f"state {s!r} is unreachable" for s in sorted(self.states - reached)]
        predecessors: dict[str, set[str]] = {s: set() for s in self.states}
        for source, targets in successors.items():
            for target in targets:
                predecessors[target].add(source)
        finishing = _closure(set(self.final), predecessors)
        problems += [f"no final state can be reached from {s!r}" for s in sorted(self.states - finishing)]
        return problems

    def allowed(self, state: str) -> list[tuple[Role, Performative, bool]]:
        """What may be sent in ``state``: (role, performative, terminal) triples, where
        ``terminal`` is True for a transition taken only by a terminal ``inform``."""
        out = {
            (role, perf, terminal) for (source, role, perf), _, terminal in self._edges() if source == state
        }
        return sorted(out, key=lambda x: (_ROLES.index(x[0]), x[1].value, x[2]))

    def next_state(
        self,
        state: str,
        role: Role,
        performative: Performative,
        terminal: bool = False,
        crossing: bool = False,
    ) -> str | None:
        """The state after ``role`` sends ``performative`` in ``state``, or None when the
        protocol does not allow it. With ``terminal`` a terminal transition is preferred; with
        ``crossing`` (the communicate may have crossed the other party's latest on the wire) a
        crossing transition is taken where no other is."""
        key = (state, role, performative)
        if terminal and key in self.terminal_transitions:
            return self.terminal_transitions[key]
        target = self.transitions.get(key)
        if target is None and crossing:
            return self.crossing_transitions.get(key)
        return target

    def to_dot(self, *, not_understood: bool = False) -> str:
        """The state machine in Graphviz DOT: the initial state marked by an arrow from a
        point, final states as double circles, edges labelled ``I: request`` (initiator)
        or ``P: inform [terminal]`` (participant). ``not-understood`` edges are drawn only
        when ``not_understood`` is true (they go from every state but the first)."""
        labels: dict[tuple[str, str], list[str]] = {}
        for (source, role, perf), target, terminal in self._edges():
            if perf is Performative.NOT_UNDERSTOOD and not not_understood:
                continue
            label = f"{_ABBREV[role]}: {perf.value}" + (" [terminal]" if terminal else "")
            labels.setdefault((source, target), []).append(label)
        states = sorted(self.states)
        if not not_understood:
            states = [s for s in states if s != "not-understood" or any(s in edge for edge in labels)]
        lines = [
            f"digraph {_q(self.name)} {{",
            "  rankdir=LR;",
            f"  label={_q(f'{self.name} ({self.spec})' if self.spec else self.name)};",
            "  node [shape=circle];",
            "  __start [shape=point];",
            f"  __start -> {_q(self.initial)};",
        ]
        for s in states:
            shape = "doublecircle" if s in self.final else "circle"
            lines.append(f"  {_q(s)} [shape={shape}];")
        for (source, target), texts in sorted(labels.items()):
            lines.append(f"  {_q(source)} -> {_q(target)} [label={_q(chr(10).join(texts))}];")
        lines.append("}")
        return "\n".join(lines) + "\n"


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _closure(start: set[str], graph: Mapping[str, set[str]]) -> set[str]:
    seen = set(start)
    todo = list(start)
    while todo:
        for nxt in graph.get(todo.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


class ProtocolViolation(ValueError):
    """A message the protocol does not allow in the conversation's current state.

    Attributes: ``protocol`` (name), ``state``, ``role``, ``performative`` of the offending
    message, ``allowed``: what :meth:`Protocol.allowed` permits in that state, ``finished``:
    the conversation had ended, and ``note``: the rule broken, when it is more than the state
    machine's (e.g. an opening communicate in a conversation already open).
    """

    def __init__(
        self,
        protocol: str,
        state: str,
        role: str,
        performative: Performative,
        allowed: list[tuple[Role, Performative, bool]],
        finished: bool = False,
        note: str = "",
    ) -> None:
        self.protocol = protocol
        self.state = state
        self.role = role
        self.performative = performative
        self.allowed = allowed
        self.finished = finished
        self.note = note
        if note:
            text = f"{protocol}: the {role} may not send {performative.value!r} in state {state!r}: {note}"
        elif finished:
            text = (
                f"{protocol}: the conversation already ended in state {state!r}; "
                f"the {role} may not send {performative.value!r}"
            )
        else:
            if allowed:
                options = ", ".join(f"{r} {p.value}" + (" (terminal)" if t else "") for r, p, t in allowed)
            else:
                options = "nothing"
            text = (
                f"{protocol}: the {role} may not send {performative.value!r} in state "
                f"{state!r}; allowed: {options}"
            )
        super().__init__(text)


REPORT_LANGUAGE = "L_SW"
"""The content language of a supervised worker's reports (:func:`is_terminal_report`): a
communicate in another is none, which a caller on the hot path tells without the call."""


def is_terminal_report(msg: Communicate) -> bool:
    """True when ``msg`` is an ``inform`` whose L_SW content reports a terminal
    supervised-worker state (Succeeded, Error, Preempted, Replan; paper §5.4)."""
    if msg.language != REPORT_LANGUAGE or msg.performative is not Performative.INFORM:
        # asked of every communicate sent and received: no import on this path, and the
        # language first (an enum member's lookup on its class costs 0.1–0.3 µs on CPython 3.11, timeit)
        return False
    from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWStatus

    try:
        status = decode_content(msg.language, msg.content)
    except ContentError:
        return False
    return isinstance(status, SWStatus) and status.state in TERMINAL_SW_STATES


# ---------------------------------------------------------------------------------------------
# The protocol library

_I: Final = "initiator"
_R: Final = "participant"  # the responder
_P = Performative


def _build(
    name: str,
    spec: str,
    description: str,
    edges: Iterable[tuple[str, Role, Performative | tuple[Performative, ...], str]],
    final: Iterable[str],
    *,
    cancellable: Iterable[str] = (),
    terminal_edges: Iterable[tuple[str, Role, Performative, str]] = (),
    initial: str = "start",
    crossing_edges: Iterable[tuple[str, Role, Performative, str]] = (),
) -> Protocol:
    """A protocol from its edges, adding the cancel meta-protocol from the ``cancellable``
    states and ``not-understood`` from every state but the initial and the final ones (with
    the final state ``not-understood`` only when some state has it: not in a protocol whose
    every state after the first is final, such as one ``inform`` that nothing answers).
    ``crossing_edges`` are :attr:`Protocol.crossing_transitions`; the cancel meta-protocol
    adds its own: what the participant may send where a cancel found the conversation,
    arriving after it (an ``agree`` leaves it cancelling, a final answer ends it as it would
    have)."""
    transitions: dict[Key, str] = {}
    crossing: dict[Key, str] = {}
    finals = set(final)

    def add(table: dict[Key, str], key: Key, target: str) -> None:
        if key in table and table[key] != target:
            raise ValueError(f"{name}: {key} leads to both {table[key]!r} and {target!r}")
        table[key] = target

    for source, role, perfs, target in edges:
        for perf in perfs if isinstance(perfs, tuple) else (perfs,):
            add(transitions, (source, role, perf), target)
    terminal: dict[Key, str] = {}
    for source, role, perf, target in terminal_edges:
        add(terminal, (source, role, perf), target)
    for source, role, perf, target in crossing_edges:
        add(crossing, (source, role, perf), target)
    cancellable = list(cancellable)
    if cancellable:
        for source in cancellable:
            add(transitions, (source, _I, _P.CANCEL), "cancelling")
        add(transitions, ("cancelling", _R, _P.INFORM), "cancelled")
        add(transitions, ("cancelling", _R, _P.FAILURE), "cancel-failed")
        # what the participant sent before the cancel arrived crosses it: a final answer (a
        # refuse, an inform-ref …) ends the conversation as it would have, any other (an
        # agree, a propose) leaves it cancelling
        for (source, role, perf), target in list(transitions.items()):
            key: Key = ("cancelling", PARTICIPANT, perf)
            if source in cancellable and role == _R and key not in transitions and key not in crossing:
                crossing[key] = target if target in finals else "cancelling"
        finals |= {"cancelled", "cancel-failed"}
    states = {initial} | finals
    for (source, _, _), target in [*transitions.items(), *terminal.items()]:
        states |= {source, target}
    answerable = sorted(states - finals - {initial})
    for source in answerable:
        for role in _ROLES:
            add(transitions, (source, role, _P.NOT_UNDERSTOOD), "not-understood")
    if answerable:  # a one-message protocol has no state to answer in: no such state either
        finals.add("not-understood")
        states.add("not-understood")
    return Protocol(
        name=name,
        states=frozenset(states),
        initial=initial,
        final=frozenset(finals),
        transitions=transitions,
        terminal_transitions=terminal,
        spec=spec,
        description=description,
        crossing_transitions=crossing,
    )


FIPA_REQUEST = _build(
    "fipa-request",
    "FIPA SC00026",
    "The initiator requests an action; the participant refuses, or agrees and later "
    "reports failure or inform (done/result). The agree may be left out when the answer "
    "comes at once (SC00026 §2).",
    [
        ("start", _I, _P.REQUEST, "requested"),
        ("requested", _R, _P.REFUSE, "refused"),
        ("requested", _R, _P.AGREE, "agreed"),
        ("requested", _R, _P.FAILURE, "failed"),
        ("requested", _R, _P.INFORM, "done"),
        ("agreed", _R, _P.FAILURE, "failed"),
        ("agreed", _R, _P.INFORM, "done"),
    ],
    ["refused", "failed", "done"],
    cancellable=["requested", "agreed"],
)

FIPA_QUERY = _build(
    "fipa-query",
    "FIPA SC00027",
    "The initiator asks query-if (is it true?) or query-ref (which objects?); the "
    "participant refuses, or (optionally after agree) answers inform or reports failure "
    "(SC00027 §2): a query-if is answered by inform (inform-t/f), a query-ref by inform "
    "(inform-result) or inform-ref, as the paper's a_km sends it (paper §5.4, Figure 9).",
    [
        ("start", _I, _P.QUERY_REF, "queried"),
        ("queried", _R, _P.REFUSE, "refused"),
        ("queried", _R, _P.AGREE, "agreed"),
        ("queried", _R, _P.FAILURE, "failed"),
        ("queried", _R, (_P.INFORM, _P.INFORM_REF), "answered"),
        ("agreed", _R, _P.FAILURE, "failed"),
        ("agreed", _R, (_P.INFORM, _P.INFORM_REF), "answered"),
        ("start", _I, _P.QUERY_IF, "queried-if"),
        ("queried-if", _R, _P.REFUSE, "refused"),
        ("queried-if", _R, _P.AGREE, "agreed-if"),
        ("queried-if", _R, _P.FAILURE, "failed"),
        ("queried-if", _R, _P.INFORM, "answered"),
        ("agreed-if", _R, _P.FAILURE, "failed"),
        ("agreed-if", _R, _P.INFORM, "answered"),
    ],
    ["refused", "failed", "answered"],
    cancellable=["queried", "agreed", "queried-if", "agreed-if"],
)

FIPA_REQUEST_WHEN = _build(
    "fipa-request-when",
    "FIPA SC00028",
    "The initiator asks for an action to be done when a precondition becomes true; the "
    "participant refuses or agrees, and once the condition holds and the action is "
    "attempted, reports failure or inform (SC00028 §2).",
    [
        ("start", _I, _P.REQUEST_WHEN, "requested"),
        ("requested", _R, _P.REFUSE, "refused"),
        ("requested", _R, _P.AGREE, "agreed"),
        ("agreed", _R, _P.FAILURE, "failed"),
        ("agreed", _R, _P.INFORM, "done"),
    ],
    ["refused", "failed", "done"],
    cancellable=["requested", "agreed"],
)

FIPA_SUBSCRIBE = _build(
    "fipa-subscribe",
    "FIPA SC00035",
    "The initiator subscribes to changes of an object; the participant refuses, or agrees "
    "and then informs at every change until it fails or the initiator cancels "
    "(cancel answered by inform or failure) (SC00035 §2).",
    [
        ("start", _I, _P.SUBSCRIBE, "subscribed"),
        ("subscribed", _R, _P.REFUSE, "refused"),
        ("subscribed", _R, _P.AGREE, "active"),
        ("active", _R, _P.INFORM, "active"),
        ("active", _R, _P.FAILURE, "failed"),
    ],
    ["refused", "failed"],
    cancellable=["subscribed", "active"],
)

FIPA_CONTRACT_NET = _build(
    "fipa-contract-net",
    "FIPA SC00029",
    "The initiator calls for proposals (cfp); the participant refuses or proposes; the "
    "initiator rejects or accepts the proposal; an accepted participant reports failure "
    "or inform (done/result); the initiator may cancel at any point (the cancel "
    "meta-protocol). A second cfp is fipa-iterated-contract-net's, not this protocol's. "
    "Tracked per participant (SC00029 §2).",
    [
        ("start", _I, _P.CFP, "cfp-sent"),
        ("cfp-sent", _R, _P.REFUSE, "refused"),
        ("cfp-sent", _R, _P.PROPOSE, "proposed"),
        ("proposed", _I, _P.REJECT_PROPOSAL, "rejected"),
        ("proposed", _I, _P.ACCEPT_PROPOSAL, "accepted"),
        ("accepted", _R, _P.FAILURE, "failed"),
        ("accepted", _R, _P.INFORM, "done"),
    ],
    ["refused", "rejected", "failed", "done"],
    cancellable=["cfp-sent", "proposed", "accepted"],
)

FIPA_ITERATED_CONTRACT_NET = _build(
    "fipa-iterated-contract-net",
    "FIPA SC00030",
    "The initiator calls for proposals (cfp); the participant refuses or proposes; the "
    "initiator rejects or accepts the proposal, or re-iterates with a revised cfp (a new "
    "round); an accepted participant reports failure or inform (done/result); the initiator "
    "may cancel at any point (the cancel meta-protocol). Tracked per participant (SC00030 §2).",
    [
        ("start", _I, _P.CFP, "cfp-sent"),
        ("cfp-sent", _R, _P.REFUSE, "refused"),
        ("cfp-sent", _R, _P.PROPOSE, "proposed"),
        ("proposed", _I, _P.CFP, "cfp-sent"),  # re-iterate: a revised cfp
        ("proposed", _I, _P.REJECT_PROPOSAL, "rejected"),
        ("proposed", _I, _P.ACCEPT_PROPOSAL, "accepted"),
        ("accepted", _R, _P.FAILURE, "failed"),
        ("accepted", _R, _P.INFORM, "done"),
    ],
    ["refused", "rejected", "failed", "done"],
    cancellable=["cfp-sent", "proposed", "accepted"],
)

FIPA_ENGLISH_AUCTION = _build(
    "fipa-english-auction",
    "FIPA SC00031",
    "The auctioneer (initiator) informs of the start of the auction, then calls rising "
    "prices (cfp); the participant bids (propose) or stays silent. The auctioneer accepts a "
    "bid (accept-proposal: the participant leads) or rejects it (reject-proposal: too late "
    "or too low); a leader outbid later, or whose bid stays below the reservation price, is "
    "told by reject-proposal too, so that the participant leading at the end is the winner. "
    "The auctioneer informs of the end of the auction and requests the winner to complete "
    "the sale. A price called, or the end, may cross a bid on the wire. Tracked per "
    "participant (SC00031 §2).",
    [
        ("start", _I, _P.INFORM, "announced"),  # inform(start-auction)
        ("announced", _I, _P.CFP, "called"),
        ("called", _I, _P.CFP, "called"),  # a higher price: no bid from this participant
        ("called", _R, _P.PROPOSE, "bid"),
        ("called", _I, _P.INFORM, "ended"),  # inform(end-of-auction)
        ("bid", _I, _P.ACCEPT_PROPOSAL, "leading"),
        ("bid", _I, _P.REJECT_PROPOSAL, "called"),
        ("leading", _I, _P.CFP, "leading"),  # a higher price called: nobody has outbid it yet
        ("leading", _I, _P.REJECT_PROPOSAL, "called"),  # outbid, or below the reservation price
        ("leading", _I, _P.INFORM, "won"),  # inform(end-of-auction) to the winner
        ("won", _I, _P.REQUEST, "requested"),  # the winner asked to complete the sale
    ],
    ["ended", "requested"],
    crossing_edges=[
        ("bid", _I, _P.CFP, "bid"),  # a higher price called before the bid arrived
        ("bid", _I, _P.INFORM, "ended"),  # the auction ended before the bid arrived
    ],
)

FIPA_DUTCH_AUCTION = _build(
    "fipa-dutch-auction",
    "FIPA SC00032",
    "The auctioneer (initiator) informs of the start of the auction, then calls falling "
    "prices (cfp); the participant bids (propose) or stays silent; the first bid is "
    "accepted (accept-proposal), a later one rejected (reject-proposal); the auctioneer "
    "informs of the end of the auction (a bid won, or the reservation price was reached "
    "unsold), and requests the winner to complete the sale. A lower price called, or the "
    "end, may cross a bid on the wire. Tracked per participant (SC00032 §2).",
    [
        ("start", _I, _P.INFORM, "announced"),  # inform(start-auction)
        ("announced", _I, _P.CFP, "called"),
        ("called", _I, _P.CFP, "called"),  # a lower price: no bid from this participant
        ("called", _R, _P.PROPOSE, "bid"),
        ("called", _I, _P.INFORM, "ended"),  # inform(end-of-auction)
        ("bid", _I, _P.ACCEPT_PROPOSAL, "accepted"),
        ("bid", _I, _P.REJECT_PROPOSAL, "rejected"),  # another bid came first
        ("rejected", _I, _P.INFORM, "ended"),
        ("accepted", _I, _P.INFORM, "won"),  # inform(end-of-auction) to the winner
        ("won", _I, _P.REQUEST, "requested"),  # the winner asked to complete the sale
    ],
    ["ended", "requested"],
    crossing_edges=[
        ("bid", _I, _P.CFP, "bid"),  # a lower price called before the bid arrived
        ("bid", _I, _P.INFORM, "ended"),  # the auction ended before the bid arrived
    ],
)

FIPA_BROKERING = _build(
    "fipa-brokering",
    "FIPA SC00033",
    "The initiator asks a broker to proxy a communicative act to the agents that match a "
    "description (proxy); the broker refuses or agrees, then reports failure (no-match: no "
    "agent found; proxy: the proxied act failed) or forwards the targets' replies "
    "(inform, reply-message). Tracked per broker (SC00033 §2).",
    [
        ("start", _I, _P.PROXY, "proxied"),
        ("proxied", _R, _P.REFUSE, "refused"),
        ("proxied", _R, _P.AGREE, "agreed"),
        ("agreed", _R, _P.FAILURE, "failed"),
        ("agreed", _R, _P.INFORM, "replied"),
    ],
    ["refused", "failed", "replied"],
    cancellable=["proxied", "agreed"],
)

FIPA_RECRUITING = _build(
    "fipa-recruiting",
    "FIPA SC00034",
    "The initiator asks a recruiter to proxy a communicative act to the agents that match a "
    "description (proxy); the recruiter refuses or agrees, then reports failure (no-match: "
    "no agent found; proxy: the proxied act failed) or inform (done: proxied). The targets' "
    "replies go to the designated receiver (reply-to), not through the recruiter, in "
    "conversations of their own. Tracked per recruiter (SC00034 §2).",
    [
        ("start", _I, _P.PROXY, "proxied"),
        ("proxied", _R, _P.REFUSE, "refused"),
        ("proxied", _R, _P.AGREE, "agreed"),
        ("agreed", _R, _P.FAILURE, "failed"),
        ("agreed", _R, _P.INFORM, "done"),
    ],
    ["refused", "failed", "done"],
    cancellable=["proxied", "agreed"],
)

FIPA_PROPOSE = _build(
    "fipa-propose",
    "FIPA SC00036",
    "The initiator proposes to perform an action; the participant accepts or rejects the "
    "proposal (SC00036 §2).",
    [
        ("start", _I, _P.PROPOSE, "proposed"),
        ("proposed", _R, _P.ACCEPT_PROPOSAL, "accepted"),
        ("proposed", _R, _P.REJECT_PROPOSAL, "rejected"),
    ],
    ["accepted", "rejected"],
)

PROTOCOLS: dict[str, Protocol] = {
    p.name: p
    for p in (
        FIPA_REQUEST,
        FIPA_QUERY,
        FIPA_REQUEST_WHEN,
        FIPA_SUBSCRIBE,
        FIPA_CONTRACT_NET,
        FIPA_ITERATED_CONTRACT_NET,
        FIPA_ENGLISH_AUCTION,
        FIPA_DUTCH_AUCTION,
        FIPA_BROKERING,
        FIPA_RECRUITING,
        FIPA_PROPOSE,
    )
}
"""The eleven interaction protocols of the FIPA library by their FIPA ``protocol`` parameter
value (FIPA SC00025). The application's own protocols are declared in its specification
(services/spec/robot_companion.toml: the paper's ``coordinate``, §5.4 Figure 8; built by
services/spec/protocol_defs.py with :func:`_build`)."""
