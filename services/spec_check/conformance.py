"""``roco spec verify RUN``: the recorded traffic of a run conforms to the specification.

The paper's claim (§4 steps 3–4, §5.4) is that the implementation is verified against the
specification. At run time every agent checks what it sends and receives
(``services.runtime.agent``); this module checks, after the fact, everything the traffic
recorder saw (``traffic.jsonl`` and ``traffic.msgpack`` of a run folder):

Every communicate (FIPA SC00061):

- it is a communicate (the payload decodes) and its key ``roco/fipa/<channel>/<sender>/<receiver>``
  names its sender and one of its receivers;
- a channel of the specification joins sender and receiver, and it is the key's channel;
- its protocol is one of that channel's, and the sender's role in it (initiator or
  participant) may send its performative (``not-understood`` always);
- its content is in a language the specification gives for that performative, with the
  language's ontology (O_RoCo; O_Velma for L_EX), and decodes in it; or, for ``failure``,
  ``refuse`` and ``not-understood``, it is a reason in UTF-8 text.

Every conversation (one conversation-id between two agents) follows its interaction
protocol's state machine (FIPA SC00026 fipa-request, SC00027 fipa-query, SC00035
fipa-subscribe, the paper's coordinate protocol, or one the specification declares),
message by message in causal order (arrival order, with an answer that arrived before what
it answers moved after it: :mod:`services.recorder.causal`), by
the rules the agents' runtime follows it by (:func:`services.runtime.protocol_state.judge`,
the one home of FIPA's rules on a conversation): communicates of the two agents that crossed
on the wire are tolerated, as are the cancel meta-protocol's late cancels; an opening
communicate in a conversation already open or ended is a violation (a conversation-id names
one conversation, SC00061; a byte-identical copy is a retransmission, judged once); so is
anything after the conversation's end, whoever sends it; a ``not-understood`` comes only from
the receiver of a communicate of the conversation it has not answered so already, and ends it:
after it, only what the other agent sent before it saw the not-understood belongs there. A
subscribe (fipa-subscribe, SC00035
§2: the participant answers agree or refuse) that the record ends with no answer to is a
violation (``unanswered``) once its reply-by has passed, or when it has none, unless the presence
record (``presence.jsonl``) shows its receiver away when it was sent or gone before its reply-by
(or, with none, before the record's end): then it was lost with the receiver's process (a put to
a process that is not there reaches nobody) and is listed as such, not counted. Other conversations
still open when the record ends are listed, not counted as violations: an agreed subscription
lasts while the system runs, and a run cut short leaves others.

:func:`verify_run` returns a :class:`ConformanceReport`; :func:`render` writes it as text;
:func:`verify_report` is what the CLI prints.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from services.recorder.causal import causal_order, send_order
from services.recorder.integrity import Integrity
from services.recorder.presence import absences, away_between, read_presence
from services.report.load import Message, load_run
from services.runtime import keys
from services.runtime.protocol_state import (
    ConversationError,
    CrossingTracker,
    expected_ontology,
    judge,
)
from services.spec.model import (
    DEFAULT_SPEC,
    NOT_UNDERSTOOD,
    ChannelProtocol,
    ChannelSpec,
    MessageKind,
    SpecError,
    SystemSpec,
    channel_between,
    interface,
    load,
)
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.protocols import (
    INITIATOR,
    PARTICIPANT,
    Protocol,
    Role,
    is_terminal_report,
)

__all__ = [
    "KINDS",
    "ConformanceReport",
    "ConversationResult",
    "Violation",
    "render",
    "verify_report",
    "verify_run",
]

_REASONS = frozenset({"failure", "refuse", NOT_UNDERSTOOD})
"""Performatives whose content may be a plain UTF-8 reason instead of a language term."""

KINDS = {
    "malformed": "the payload is not a communicate",
    "key": "the key does not name the communicate's sender and receiver",
    "channel": "no channel of the specification joins the agents, or another channel does",
    "performative": "the protocol or performative is not allowed for the sender's role there",
    "language": "the content language is not the one specified",
    "ontology": "the ontology is not the content language's",
    "content": "the content does not decode in its language",
    "protocol-state": "the performative is not allowed in the conversation's protocol state",
    "conversation": "the communicate cannot belong to its conversation",
    "unanswered": "a subscribe was never agreed nor refused (by its reply-by, or by the record's end)",
}
"""The kinds of violation, with what each means."""


@dataclass(frozen=True)
class Violation:
    """One communicate that falls outside the specification.

    ``seq``: its index in the traffic record (arrival order at the recorder); ``t``: its time
    in s since the run began; ``kind``: one of :data:`KINDS`; ``conversation``: its
    conversation-id (None: none); ``position``: its index (0-based) within that conversation
    (None: not in one); ``text``: what is wrong, for a person (for ``protocol-state``, the
    state machine's own message)."""

    seq: int
    t: float
    kind: str
    channel: str
    sender: str
    receiver: str
    performative: str
    protocol: str | None
    conversation: str | None
    position: int | None
    text: str


@dataclass
class ConversationResult:
    """One conversation as followed: its ``conversation_id``, the two ``agents`` (initiator
    first when known), ``protocol``, number of ``messages``, final ``state`` (the first
    reading's; see :class:`~services.runtime.protocol_state.CrossingTracker`), whether it
    ``ended`` (some reading reached a final state), ``violations`` in it, ``crossings``
    tolerated, ``not_understood`` True when a not-understood ended it, ``answered`` False when
    the participant sent nothing after the latest opening communicate, ``unanswered`` True for
    a subscribe left so past its reply-by (a violation), ``lost`` what says a subscribe left
    unanswered was lost with its receiver's process instead (empty: not so), and the times
    ``first_t``/``last_t`` (s since run start)."""

    conversation_id: str
    agents: tuple[str, str]
    protocol: str
    messages: int = 0
    state: str = ""
    ended: bool = False
    violations: int = 0
    crossings: int = 0
    not_understood: bool = False
    answered: bool = True
    unanswered: bool = False
    lost: str = ""
    first_t: float = 0.0
    last_t: float = 0.0

    @property
    def open_by_design(self) -> bool:
        """True for an agreed subscription still active: it lasts as long as the system runs."""
        return self.protocol == "fipa-subscribe" and not self.ended and self.answered


@dataclass
class ConformanceReport:
    """What :func:`verify_run` found in one run folder.

    ``communicates``: records checked; ``conversations``: every conversation followed;
    ``violations``: every communicate outside the specification, in arrival order;
    ``unchecked``: communicates whose payload was missing, so only their record was checked;
    ``copies``: communicates recorded again byte for byte on the same key (a retransmission,
    answers published again for a copy, a duplicate of the network:
    :attr:`services.report.load.Message.copy_of`), counted and not checked again;
    ``not_understood``: the not-understood communicates (an agent refused something; each is
    listed with its reason as a :class:`Violation`-shaped entry of kind ``not-understood``);
    ``notes``: problems reading the run folder.
    """

    run_dir: Path
    system: str
    communicates: int = 0
    conversations: list[ConversationResult] = field(default_factory=list)
    violations: list[Violation] = field(default_factory=list)
    unchecked: int = 0
    copies: int = 0
    not_understood: list[Violation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    outside_estimates: list[str] = field(default_factory=list)
    """Communicates whose size on the wire fell outside the specification's estimate (not a
    violation: estimates, paper eq. 4)."""
    record: Integrity = field(default_factory=Integrity)
    """The traffic record's integrity, checked first (services/recorder/integrity.py): a
    record that lost or mispaired communicates cannot show conformance."""

    @property
    def per_protocol(self) -> dict[str, int]:
        """Number of conversations per interaction protocol."""
        return dict(sorted(Counter(c.protocol for c in self.conversations).items()))

    @property
    def conforming(self) -> int:
        """Conversations none of whose communicates is a violation."""
        return sum(1 for c in self.conversations if c.violations == 0)

    @property
    def open_conversations(self) -> list[ConversationResult]:
        """Conversations no reading of which had ended when the record ended."""
        return [c for c in self.conversations if not c.ended and not c.not_understood]

    @property
    def full_conformance(self) -> bool:
        """True when communicates were recorded, the record is intact, every one was checked in
        full, and none is a violation."""
        return self.communicates > 0 and self.record.intact and self.unchecked == 0 and not self.violations


# ---------------------------------------------------------------------------------------------


def verify_run(
    run_dir: Path, spec: SystemSpec, *, protocols: Mapping[str, Protocol] | None = None
) -> ConformanceReport:
    """Check the recorded traffic of ``run_dir`` against ``spec`` (see the module docstring).

    ``protocols`` maps protocol names to their state machines (default: ``spec``'s, each the
    one its ``[protocols.NAME]`` table declares or the built-in one,
    :func:`services.spec.protocol_defs.machine_of`); a protocol without one is checked per
    communicate only. Raises FileNotFoundError when ``run_dir`` is not a folder; anything
    unreadable inside it becomes a note (``services.report.load``)."""
    machines = dict(_machines_of(spec) if protocols is None else protocols)
    data = load_run(Path(run_dir))
    # the loader tries every content in its language; the checks below judge content
    # themselves, so its note on undecodable content is left out
    notes = [
        n
        for n in data.notes
        if "not decodable in their language" not in n and not n.startswith("traffic record ")
    ]
    report = ConformanceReport(Path(run_dir), spec.system, notes=notes, record=data.integrity)
    messages, moved = causal_order(data.messages)
    if moved:
        notes.append(
            f"{moved} communicate(s) reached the recorder before the one they answer "
            "(publishers' paths through the router are not ordered); checked in causal order"
        )
    messages, crossed = send_order(messages)
    if crossed:
        notes.append(
            f"{crossed} communicate(s) reached the recorder after one the other party sent later "
            "in the same conversation; checked in the order they were sent"
        )
    try:
        presence = read_presence(Path(run_dir))
    except OSError as e:
        presence = None
        notes.append(f"presence record unreadable ({e}): no subscribe is taken as lost with its receiver")
    checker = _Checker(spec, machines, report, absences(presence) if presence else {})
    for message in messages:
        checker.check(message)
    checker.finish()
    return report


def _machines_of(spec: SystemSpec) -> dict[str, Protocol]:
    """The state machine of every protocol ``spec`` names that has one."""
    from services.spec.protocol_defs import machine_of

    machines = {}
    for name in spec.protocols:
        try:
            machines[name] = machine_of(spec, name)
        except SpecError:  # no machine (or a malformed one: roco spec check says which)
            continue
    return machines


Problem = tuple[str, str]
"""(kind, text) of one violation."""


@dataclass
class _SpecRules:
    """The specification's rules on one communicate ``m`` on channel ``between`` (paper §4
    step 4: the sender's interface yV̂, the receiver's xV̂, the languages yL̂/xL̂), one method
    per rule, judged in :data:`_RULES`' order: a rule returns the problems that end the
    judgement (an empty list: nothing more to judge), or None to go on; the last rule,
    :meth:`ontology_and_content`, gathers its problems. A size outside the estimate goes to
    ``outside_estimates`` (not a violation)."""

    m: Message
    sender: str
    receiver: str
    between: ChannelSpec
    sends: list[MessageKind]
    """What the sender's role may send to the receiver's in the communicate's protocol."""
    s_role: str
    outside_estimates: list[str]
    kind: MessageKind | None = None
    """The sender's interface entry for the communicate, once :meth:`performative` found it."""

    @property
    def perf(self) -> str:
        return self.m.rec.performative

    @property
    def protocol(self) -> str | None:
        return self.m.rec.protocol

    @property
    def language(self) -> str | None:
        return self.m.comm.language if self.m.comm is not None else self.m.rec.language

    def channel(self) -> list[Problem] | None:
        if self.between.name != self.m.rec.channel:
            joined = f"{self.sender} and {self.receiver} are joined by {self.between.name}"
            return [("channel", f"{joined}, not {self.m.rec.channel}")]
        return None

    def unnamed_protocol(self) -> list[Problem] | None:
        """The answer to a payload that was no communicate: no protocol to name."""
        return [] if self.perf == NOT_UNDERSTOOD and self.protocol is None else None

    def protocol_on_channel(self) -> list[Problem] | None:
        if self.protocol in {cp.protocol for cp in self.between.protocols}:
            return None
        offered = ", ".join(cp.protocol for cp in self.between.protocols)
        return [
            ("performative", f"protocol {self.protocol} is not specified on {self.between.name} ({offered})")
        ]

    def performative(self) -> list[Problem] | None:
        self.kind = next((k for k in self.sends if k.performative == self.perf), None)
        if self.kind is not None:
            return None
        role = _role_of(self.between, self.protocol, self.s_role)
        allowed = ", ".join(k.performative for k in self.sends)
        return [
            (
                "performative",
                f"the {role} of {self.protocol} on {self.between.name} ({self.sender}) may not send "
                f"{self.perf} (allowed: {allowed})",
            )
        ]

    def reason(self) -> list[Problem] | None:
        """``failure``, ``refuse`` and ``not-understood`` may carry a reason in UTF-8 text."""
        comm = self.m.comm
        if comm is None or comm.language is not None or comm.encoding != "utf-8" or self.perf not in _REASONS:
            return None
        try:
            comm.content.decode("utf-8")
        except UnicodeDecodeError as exc:
            return [("content", f"the reason is not UTF-8 text: {exc.reason}")]
        return []

    def language_given(self) -> list[Problem] | None:
        comm, language = self.m.comm, self.language
        has_content = bool(comm.content) if comm is not None else language is not None
        if not has_content:
            return None
        if language is None:
            return [("language", f"{self.perf} carries content but names no language")]
        assert self.kind is not None
        if self.kind.languages and language not in self.kind.languages:
            return [
                (
                    "language",
                    f"{self.perf} in {self.protocol} on {self.between.name} must be in "
                    f"{'/'.join(self.kind.languages)}, not {language}",
                )
            ]
        return None

    def ontology_and_content(self) -> list[Problem]:
        language = self.language
        if language is None:
            return []
        ontology = self.m.comm.ontology if self.m.comm is not None else self.m.rec.ontology
        problems: list[Problem] = []
        if ontology != expected_ontology(language):
            needed = expected_ontology(language)
            problems.append(("ontology", f"language {language} needs ontology {needed}, not {ontology}"))
        return problems + self.content(language)

    def content(self, language: str) -> list[Problem]:
        """The content decodes in its language, as a term the channel's protocol allows; its
        size is measured against the estimate."""
        comm = self.m.comm
        if comm is None or not comm.content:
            return []
        try:
            term = decode_content(language, comm.content)
        except ContentError as exc:
            return [("content", str(exc))]
        cp = next(c for c in self.between.protocols if c.protocol == self.protocol)
        self.estimate(cp)
        allowed_terms = cp.content_types(self.perf)
        if allowed_terms and type(term).__name__ not in allowed_terms:
            return [
                (
                    "content",
                    f"{self.perf} in {self.protocol} on {self.between.name} carries a {type(term).__name__}; "
                    f"the specification allows {', '.join(allowed_terms)}",
                )
            ]
        return []

    def estimate(self, cp: ChannelProtocol) -> None:
        size, estimate = self.m.rec.size, cp.sizes.get(self.perf)
        if estimate is not None and not estimate[0] <= size <= estimate[1]:
            low, high = estimate
            self.outside_estimates.append(
                f"{self.between.name} {self.protocol} {self.perf}: {size} B (estimate {low}–{high} B)"
            )


_RULES = (
    _SpecRules.channel,
    _SpecRules.unnamed_protocol,
    _SpecRules.protocol_on_channel,
    _SpecRules.performative,
    _SpecRules.reason,
    _SpecRules.language_given,
)
"""The rules that may end the judgement of a communicate, in the order they are judged."""


def _violation(
    m: Message, receiver: str, result: ConversationResult | None, kind: str, text: str
) -> Violation:
    """``m``'s violation of ``kind``, judged by ``receiver``, at its place in ``result``."""
    rec = m.rec
    return Violation(
        seq=rec.seq,
        t=m.t,
        kind=kind,
        channel=rec.channel,
        sender=rec.sender,
        receiver=receiver,
        performative=rec.performative,
        protocol=rec.protocol,
        conversation=rec.conversation_id,
        position=result.messages - 1 if result is not None else None,
        text=text,
    )


def _key_mismatches(comm: Communicate, record_channel: str, parsed: tuple[str, str, str]) -> list[Problem]:
    """Where the key ``roco/fipa/C/S/R`` (``parsed``) and the communicate or its record disagree."""
    channel, sender, receiver = parsed
    names = tuple(r.name for r in comm.receiver)
    problems: list[Problem] = []
    if comm.sender is None or comm.sender.name != sender:
        who = comm.sender.name if comm.sender else "no sender"
        problems.append(("key", f"the key names sender {sender}, the communicate {who}"))
    if receiver not in names:
        named = ", ".join(names) or "none"
        problems.append(("key", f"the key names receiver {receiver}, the communicate {named}"))
    if channel != record_channel:
        problems.append(("key", f"the key names channel {channel}, the record {record_channel}"))
    return problems


def _tracking(comm: Communicate | None) -> tuple[bool | None, str | None, str | None]:
    """What the state machine reads of a communicate beside its performative: whether it is a
    terminal report, its reply-with and in-reply-to (all None: only its record is known)."""
    if comm is None:
        return None, None, None
    return is_terminal_report(comm), comm.reply_with, comm.in_reply_to


def _performative(name: str) -> Performative | None:
    try:
        return Performative(name)
    except ValueError:
        return None


def _tally(result: ConversationResult, outcome: str) -> None:
    """Count the outcome of one step of the state machine in its conversation."""
    if outcome in ("crossing", "forgotten"):
        result.crossings += 1
    elif outcome == "aborted":
        result.not_understood = True


class _Checker:
    """Checks communicates one by one, in arrival order, and follows their conversations."""

    def __init__(
        self,
        spec: SystemSpec,
        machines: dict[str, Protocol],
        report: ConformanceReport,
        away: dict[str, list[tuple[float, float]]],
    ) -> None:
        self.spec = spec
        self.machines = machines
        self.report = report
        # agents, and the external role foreign agents play (SystemSpec.role_of)
        self.interfaces = {n: interface(spec, n) for n in (*spec.agent_names, *spec.external_names)}
        self.trackers: dict[tuple[str, frozenset[str]], CrossingTracker] = {}
        self.results: dict[tuple[str, frozenset[str]], ConversationResult] = {}
        self.openings: dict[tuple[str, frozenset[str]], tuple[Message, str, int]] = {}
        """The latest opening communicate of each conversation, its receiver and position, until
        the participant sends anything after it."""
        self.end = 0.0  # POSIX time of the last communicate recorded
        self.absences = away
        """When each process was away, from the presence record (services/recorder/presence.py
        ``absences``)."""
        self.outside_estimates = report.outside_estimates

    # ---- one communicate -----------------------------------------------------------------
    def check(self, m: Message) -> None:
        self.report.communicates += 1
        rec, comm = m.rec, m.comm
        self.end = max(self.end, rec.t)
        if m.copy_of is not None:  # the same communicate again: judged once, as the original
            self.report.copies += 1
            return
        receiver, problems, result = self._judge(m)
        for kind, text in problems:
            self.report.violations.append(_violation(m, receiver, result, kind, text))
            if result is not None:
                result.violations += 1
        if rec.performative == NOT_UNDERSTOOD:
            reason = comm.content.decode("utf-8", "replace") if comm is not None else ""
            self.report.not_understood.append(_violation(m, receiver, result, NOT_UNDERSTOOD, reason))

    def _judge(self, m: Message) -> tuple[str, list[Problem], ConversationResult | None]:
        """The receiver ``m`` is judged by, its problems, and its conversation (None: none)."""
        rec = m.rec
        receiver = rec.receivers[0] if rec.receivers else "?"
        if rec.performative == "malformed":
            return receiver, [("malformed", f"the payload on {rec.key or '?'} is not a communicate")], None
        problems: list[Problem] = []
        if m.comm is None:
            self.report.unchecked += 1
        else:
            receiver = self._key(m, problems)
        spec_problems = self._spec_problems(m, rec.sender, receiver)
        problems += spec_problems
        # a communicate outside the sender's interface has no place in a protocol state
        followed = not any(kind in ("channel", "performative") for kind, _ in spec_problems)
        return receiver, problems, self._follow(m, rec.sender, receiver, problems, followed=followed)

    def _key(self, m: Message, problems: list[Problem]) -> str:
        """Check the key against the communicate; returns the receiver to judge it by."""
        comm = m.comm
        assert comm is not None
        try:
            parsed = keys.parse_fipa_key(m.rec.key)
        except ValueError:
            problems.append(("key", f"{m.rec.key!r} is not a communicate key roco/fipa/C/S/R"))
            return comm.receiver[0].name if comm.receiver else "?"
        problems += _key_mismatches(comm, m.rec.channel, parsed)
        return parsed[2]

    def _spec_problems(self, m: Message, sender: str, receiver: str) -> list[Problem]:
        """Everything about ``m`` the specification does not allow (paper §4 step 4: the
        sender's interface yV̂, the receiver's xV̂, the languages yL̂/xL̂): the rules of
        :class:`_SpecRules`, in :data:`_RULES`' order."""
        s_role, r_role = self.spec.role_of(sender), self.spec.role_of(receiver)
        between = channel_between(self.spec, s_role, r_role)
        if between is None:
            return [("channel", f"no channel of the specification joins {sender} and {receiver}")]
        protocol = m.rec.protocol
        sends = [k for k in self.interfaces[s_role].sends if k.receiver == r_role and k.protocol == protocol]
        rules = _SpecRules(m, sender, receiver, between, sends, s_role, self.outside_estimates)
        for rule in _RULES:
            found = rule(rules)
            if found is not None:
                return found
        return rules.ontology_and_content()

    # ---- its conversation ----------------------------------------------------------------
    def _follow(
        self, m: Message, sender: str, receiver: str, problems: list[Problem], *, followed: bool
    ) -> ConversationResult | None:
        """Follow ``m`` in its conversation (``followed`` False: only count it there);
        a state problem goes to ``problems``. Returns the conversation, None when ``m``
        belongs to none."""
        rec = m.rec
        cid, protocol = rec.conversation_id, rec.protocol
        if cid is None or protocol is None:
            if protocol is not None and rec.performative != NOT_UNDERSTOOD:
                problems.append(("conversation", f"a {protocol} communicate without conversation-id"))
            return None
        key = (cid, frozenset((sender, receiver)))
        result = self._conversation(key, m, sender, receiver, protocol)
        machine = self.machines.get(protocol)
        performative = _performative(rec.performative)
        if followed and machine is not None and performative is not None:
            self._step(key, m, (sender, receiver), machine, performative, result, problems)
        elif key in self.trackers:  # outside the sender's interface: its receiver heard it all the same
            self.trackers[key].hear(INITIATOR if receiver == result.agents[0] else PARTICIPANT)
        return result

    def _conversation(
        self, key: tuple[str, frozenset[str]], m: Message, sender: str, receiver: str, protocol: str
    ) -> ConversationResult:
        """``m``'s conversation, begun when it is the first, with ``m`` counted in it."""
        result = self.results.get(key)
        if result is None:
            initiator = self._initiator(sender, receiver, protocol)
            other = receiver if initiator == sender else sender
            result = ConversationResult(key[0], (initiator, other), protocol, first_t=m.t)
            self.results[key] = result
            self.report.conversations.append(result)
        result.messages += 1
        result.last_t = m.t
        if sender != result.agents[0]:
            self.openings.pop(key, None)  # the participant answered (rightly or not: judged here)
        return result

    def _step(
        self,
        key: tuple[str, frozenset[str]],
        m: Message,
        agents: tuple[str, str],
        machine: Protocol,
        performative: Performative,
        result: ConversationResult,
        problems: list[Problem],
    ) -> None:
        """One step of the conversation's state machine (sender, receiver: ``agents``); a
        state problem goes to ``problems``."""
        sender, receiver = agents
        role: Role = INITIATOR if sender == result.agents[0] else PARTICIPANT
        terminal, reply_with, in_reply_to = _tracking(m.comm)
        tracker, outcome, refusal = judge(
            self.trackers.get(key),
            machine,
            role,
            performative,
            terminal=terminal,
            reply_with=reply_with,
            in_reply_to=in_reply_to,
            copies=False,  # a copy is judged by its bytes (Message.copy_of), not its reply-with
        )
        self.trackers[key] = tracker  # refused: its receiver heard it (it may answer not-understood)
        if isinstance(refusal, ConversationError):
            problems.append(("conversation", str(refusal)))
            return
        if refusal is not None:
            problems.append(("protocol-state", str(refusal)))
            return
        if role == INITIATOR and tracker.messages == 1 and outcome == "step":
            self.openings[key] = (m, receiver, result.messages - 1)
        assert outcome is not None
        _tally(result, outcome)

    def _initiator(self, sender: str, receiver: str, protocol: str) -> str:
        """The initiator of ``protocol`` between the agents by the specification; else the
        sender of the conversation's first communicate."""
        between = channel_between(self.spec, self.spec.role_of(sender), self.spec.role_of(receiver))
        if between is not None:
            for cp in between.protocols:
                if cp.protocol == protocol:
                    return sender if cp.initiator == self.spec.role_of(sender) else receiver
        return sender

    def finish(self) -> None:
        """Note where every conversation stands at the end of the record."""
        for key, result in self.results.items():
            tracker = self.trackers.get(key)
            if tracker is None:
                result.state = "not followed"
                result.ended = True  # nothing to say it is open
                continue
            result.state = "not-understood" if tracker.aborted else tracker.state
            result.ended = tracker.may_be_finished
            result.answered = key not in self.openings
            if result.protocol == "fipa-subscribe" and not tracker.aborted:
                self._unanswered(key, result)
        self.report.violations.sort(key=lambda v: v.seq)

    def _unanswered(self, key: tuple[str, frozenset[str]], result: ConversationResult) -> None:
        """A subscribe the participant sent nothing after (FIPA SC00035 §2: it agrees or
        refuses) is a violation once its reply-by (POSIX s) passed before the record's last
        communicate, or when it names none."""
        opening = self.openings.get(key)
        if opening is None:
            return
        m, receiver, position = opening
        reply_by = m.comm.reply_by if m.comm is not None else None
        if reply_by is not None and reply_by > self.end:
            return  # still in time when the record ended
        sent = m.rec.t_sent if m.rec.t_sent is not None else m.rec.t
        until = math.inf if reply_by is None else reply_by
        gone = away_between(self.absences.get(receiver, []), sent, until)
        if gone is not None:
            result.lost = _lost_text(receiver, gone, sent, m.rec.t - m.t)
            return
        result.unanswered = True
        result.violations += 1
        by = (
            f"its reply-by passed {self.end - reply_by:.1f} s before the record ended"
            if reply_by is not None
            else "it names no reply-by"
        )
        self.report.violations.append(
            Violation(
                seq=m.rec.seq,
                t=m.t,
                kind="unanswered",
                channel=m.rec.channel,
                sender=m.rec.sender,
                receiver=receiver,
                performative=m.rec.performative,
                protocol=m.rec.protocol,
                conversation=m.rec.conversation_id,
                position=position,
                text=f"{receiver} never agreed to nor refused the subscribe ({by})",
            )
        )


def _lost_text(receiver: str, gone: tuple[float, float], sent: float, start: float) -> str:
    """Why a subscribe was lost: when its receiver's process was away (POSIX s; ``start`` the
    run's start, printed as s since it)."""
    since, until = gone
    when = "when it was sent" if since <= sent else f"from {since - start:.3f} s, before it answered"
    back = "never came back" if math.isinf(until) else f"back at {until - start:.3f} s"
    return f"lost with {receiver}'s process: away {when}, {back}"


def _role_of(channel: ChannelSpec, protocol: str | None, agent: str) -> str:
    for cp in channel.protocols:
        if cp.protocol == protocol:
            return INITIATOR if cp.initiator == agent else PARTICIPANT
    return "sender"


# ---------------------------------------------------------------------------------------------


def _counts_lines(report: ConformanceReport) -> list[str]:
    """The record, the communicates and conversations counted, what was tolerated, copied or
    left unchecked."""
    n_conv = len(report.conversations)
    lines = [
        f"traffic record: {report.record.summary()}",
        f"communicates: {report.communicates} in {n_conv} conversations",
    ]
    if report.per_protocol:
        lines.append(
            "conversations per protocol: " + ", ".join(f"{p} {n}" for p, n in report.per_protocol.items())
        )
    lines.append(f"conforming conversations: {report.conforming} of {n_conv}")
    crossings = sum(c.crossings for c in report.conversations)
    if crossings:
        lines.append(f"tolerated: {crossings} communicate(s) crossing on the wire")
    if report.copies:
        lines.append(
            f"copies: {report.copies} communicate(s) recorded again byte for byte (retransmitted, "
            "or answers sent again for a copy): each judged once, as its original"
        )
    if report.unchecked:
        lines.append(f"unchecked: {report.unchecked} communicate(s) without payload (record checked only)")
    return lines


def _violations_lines(report: ConformanceReport, limit: int) -> list[str]:
    if not report.violations:
        return ["violations: none"]
    lines = [f"violations: {len(report.violations)}"]
    lines += ["  " + _violation_line(v) for v in report.violations[:limit]]
    if len(report.violations) > limit:
        lines.append(f"  … {len(report.violations) - limit} more")
    return lines


def _sizes_lines(report: ConformanceReport) -> list[str]:
    if not report.outside_estimates:
        return ["sizes: every communicate within the specification's estimates"]
    return [
        f"sizes outside the specification's estimates: {len(report.outside_estimates)}",
        *(f"  {x}" for x in report.outside_estimates[:10]),
    ]


def _open_why(c: ConversationResult) -> str:
    """Why a conversation open at the end of the record is so, when it says something."""
    if c.open_by_design:
        return " (an agreed subscription lasts while the system runs)"
    if c.unanswered:
        return " (never agreed nor refused: a violation)"
    if c.lost:
        return f" ({c.lost})"
    return ""


def _open_lines(report: ConformanceReport, limit: int) -> list[str]:
    still = report.open_conversations
    if not still:
        return []
    lines = [f"open at the end of the record: {len(still)}"]
    lines += [
        f"  {c.conversation_id} {c.agents[0]}→{c.agents[1]} {c.protocol} in state {c.state}, "
        f"{c.messages} communicates, last at {c.last_t:.3f} s{_open_why(c)}"
        for c in still[:limit]
    ]
    if len(still) > limit:
        lines.append(f"  … {len(still) - limit} more")
    return lines


def _not_understood_lines(report: ConformanceReport, limit: int) -> list[str]:
    if not report.not_understood:
        return []
    return [
        f"not-understood answers: {len(report.not_understood)}",
        *("  " + _violation_line(v) for v in report.not_understood[:limit]),
    ]


def _verdict(report: ConformanceReport) -> str:
    """Full conformance, or the first reason it is not."""
    if report.full_conformance:
        return "yes"
    if report.communicates == 0:
        return "no (no communicates recorded)"
    if report.violations:
        return f"no ({len(report.violations)} violation(s))"
    if not report.record.intact:
        return "no (the traffic record is not intact)"
    return f"no ({report.unchecked} communicate(s) could not be checked)"


def render(report: ConformanceReport, *, limit: int = 50) -> str:
    """``report`` as text for a person: the counts, every violation (up to ``limit``), the
    conversations left open, the not-understood answers, notes, and the verdict."""
    lines = [
        f"Conformance of {report.run_dir} to the {report.system} specification",
        *_counts_lines(report),
        *_violations_lines(report, limit),
        *_sizes_lines(report),
        *_open_lines(report, limit),
        *_not_understood_lines(report, limit),
        *(f"note: {note}" for note in report.notes),
        f"full conformance: {_verdict(report)}",
    ]
    return "\n".join(lines)


def _violation_line(v: Violation) -> str:
    where = f"conversation {v.conversation}" if v.conversation else "no conversation"
    if v.position is not None:
        where += f" #{v.position}"
    protocol = f" {v.protocol}" if v.protocol else ""
    return (
        f"seq {v.seq} t={v.t:.3f} s {v.channel} {v.sender}→{v.receiver} {v.performative}{protocol} "
        f"({where}) [{v.kind}] {v.text}"
    )


def verify_report(run_dir: Path, spec_path: Path | None = None) -> tuple[bool, str]:
    """``roco spec verify RUN``: (full conformance, the rendered report). ``spec_path``
    None means the shipped specification. A run folder that does not exist or a
    specification that does not load gives (False, the reason)."""
    from services.spec.protocol_defs import protocols_of

    try:
        spec = load(spec_path) if spec_path is not None else load()
        protocols = protocols_of(spec_path) if spec_path is not None else protocols_of(DEFAULT_SPEC)
    except SpecError as exc:
        return False, str(exc)
    try:
        report = verify_run(run_dir, spec, protocols=protocols)
    except FileNotFoundError:
        return False, f"{run_dir}: no such run folder"
    return report.full_conformance, render(report)
