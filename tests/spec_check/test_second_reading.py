"""The protocol machines checked against a second reading of the FIPA documents.

:data:`READINGS` says, for every interaction protocol roco follows (the eleven of FIPA's library,
SC00026–SC00036, and roco's own: coordinate, paper §5.4 Figure 8, and roco-notify), which
sequences of (sender, performative) FIPA allows, written from the documents in a form of its
own: a table of the steps each document draws, plus the rules every document shares, applied by
:class:`Reading` itself (the cancel meta-protocol where a document has it, a failed cancel
leaving the conversation where it was; not-understood from the receiver of the latest
communicate, ending the conversation; nothing after the end).

The sequences are sent *linked*: each communicate names the other party's latest in its
in-reply-to, so that nothing may be read as having crossed another on the wire (crossings are
a reading of arrival order, tested in tests/runtime/test_protocol_state.py). Every sequence up to
a length covering each protocol's longest path without a loop plus two is decided alike by the
table and by each follower: the runtime at the initiator's agent and at the participant's (their
``ProtocolStates``) and ``roco spec verify``'s configuration of the same rules (an observer,
copies judged by their bytes). A sequence is legal when each of its prefixes is, so it suffices
to walk the prefixes the table allows and try every communicate after each: a sequence with a
forbidden step is then decided at its first one. For the protocols of the shipped specification,
``roco spec verify`` itself judges the sequences up to four communicates, each written as a run's
record (its protocol verdict: the ``performative``, ``protocol-state`` and ``conversation``
violations)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from services.runtime.protocol_state import ProtocolStates, judge
from services.spec.model import DEFAULT_SPEC, default_spec, load
from services.spec.protocol_defs import protocols_of
from services.spec_check.conformance import verify_run
from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, PROTOCOLS, Protocol, ProtocolViolation, Role
from tests.support.recorded_run import write_recorded_run

P = Performative
I_, R_ = "I", "P"
END = "END"
Symbol = tuple[str, Performative, bool]
"""(sender: I or P, performative, terminal: an inform reporting a terminal L_SW state)."""


@dataclass(frozen=True)
class Reading:
    """One protocol as a FIPA document draws it: ``steps`` maps a state to what may be sent
    there, (sender, performative[, terminal]) → next state (``END``: the conversation is over);
    ``cancel_from``: the states where the initiator may cancel (the cancel meta-protocol: the
    participant answers inform, the cancel done, or failure, the cancel failed and the
    conversation goes on where it was, or ends there); ``source``: the document."""

    source: str
    steps: dict[str, dict[tuple[str, Performative] | Symbol, str]]
    cancel_from: frozenset[str] = frozenset()
    start: str = "start"

    def symbols(self) -> list[Symbol]:
        """Every (sender, performative, terminal) worth trying: each the document names, from
        either party, with cancel and not-understood."""
        perfs = {
            (key[1], key[2] if len(key) == 3 else False) for table in self.steps.values() for key in table
        }
        perfs |= {(P.CANCEL, False), (P.NOT_UNDERSTOOD, False), (P.INFORM, False), (P.FAILURE, False)}
        return sorted(
            ((who, perf, terminal) for who in (I_, R_) for perf, terminal in perfs),
            key=lambda s: (s[0], s[1].value, s[2]),
        )

    def after(self, at: frozenset[Where], symbol: Symbol) -> frozenset[Where]:
        """Where the conversation may stand after ``symbol`` from any of ``at`` (empty: the
        document does not allow it)."""
        return frozenset(w for here in at for w in self._after(here, symbol))

    def _after(self, here: Where, symbol: Symbol) -> Iterator[Where]:
        who, perf, terminal = symbol
        if perf is P.NOT_UNDERSTOOD:  # from the receiver of the latest communicate; it ends it all
            if here.last is not None and here.last != who and here.state != "NU":
                yield Where("NU", who)
            return
        if here.state in (END, "NU"):
            return  # nothing after the end, whoever sends it
        if here.state == "forgotten":
            if who == R_ and perf in (P.INFORM, P.FAILURE):
                yield Where(END, who)  # answered once: nothing to cancel
            return
        if here.state == self.start and here.last is None and who == I_ and perf is P.CANCEL:
            # roco's rule for a participant that forgot the conversation (restarted, or its
            # bounded table let it go): a cancel of it may come first, answered once; the
            # initiator's own runtime never sends one (FORGETFUL below)
            yield Where("forgotten", who)
            return
        if here.state.startswith("cancel:"):
            before = here.state.removeprefix("cancel:")
            if who == R_ and perf is P.INFORM and not terminal:
                yield Where(END, who)  # cancelled
            if who == R_ and perf is P.FAILURE:
                yield Where(END, who)  # could not cancel: it ends here …
                yield Where(before, who)  # … or goes on where the cancel found it
            return
        if who == I_ and perf is P.CANCEL and here.state in self.cancel_from:
            yield Where(f"cancel:{here.state}", who)
        table = self.steps.get(here.state, {})
        nxt = table.get((who, perf, terminal)) or (table.get((who, perf)) if not terminal else None)
        if nxt is not None:
            yield Where(nxt, who)


@dataclass(frozen=True)
class Where:
    """A state of a reading and who sent the latest communicate (None: nobody yet)."""

    state: str
    last: str | None = field(default=None)


def _r(source: str, steps: dict[str, dict[tuple[str, Performative] | Symbol, str]], *cancel: str) -> Reading:
    return Reading(source, steps, frozenset(cancel))


_REQUEST_LIKE = {
    "start": {(I_, P.REQUEST): "asked"},
    "asked": {(R_, P.REFUSE): END, (R_, P.AGREE): "agreed", (R_, P.FAILURE): END, (R_, P.INFORM): END},
    "agreed": {(R_, P.FAILURE): END, (R_, P.INFORM): END},
}
_PROXY = {
    "start": {(I_, P.PROXY): "asked"},
    "asked": {(R_, P.REFUSE): END, (R_, P.AGREE): "agreed"},
    "agreed": {(R_, P.FAILURE): END, (R_, P.INFORM): END},
}
_CONTRACT_NET = {
    "start": {(I_, P.CFP): "called"},
    "called": {(R_, P.REFUSE): END, (R_, P.PROPOSE): "proposed"},
    "proposed": {(I_, P.REJECT_PROPOSAL): END, (I_, P.ACCEPT_PROPOSAL): "accepted"},
    "accepted": {(R_, P.FAILURE): END, (R_, P.INFORM): END},
}

READINGS: dict[str, Reading] = {
    "fipa-request": _r("SC00026 §2: the agree may be left out", _REQUEST_LIKE, "asked", "agreed"),
    "fipa-query": _r(
        "SC00027 §2: query-if answered by inform (true or false); query-ref by inform (its "
        "result) or, as the paper's a_km answers, inform-ref",
        {
            "start": {(I_, P.QUERY_IF): "if", (I_, P.QUERY_REF): "ref"},
            "if": {
                (R_, P.REFUSE): END,
                (R_, P.AGREE): "if-agreed",
                (R_, P.FAILURE): END,
                (R_, P.INFORM): END,
            },
            "if-agreed": {(R_, P.FAILURE): END, (R_, P.INFORM): END},
            "ref": {
                (R_, P.REFUSE): END,
                (R_, P.AGREE): "ref-agreed",
                (R_, P.FAILURE): END,
                (R_, P.INFORM): END,
                (R_, P.INFORM_REF): END,
            },
            "ref-agreed": {(R_, P.FAILURE): END, (R_, P.INFORM): END, (R_, P.INFORM_REF): END},
        },
        "if",
        "if-agreed",
        "ref",
        "ref-agreed",
    ),
    "fipa-request-when": _r(
        "SC00028 §2: agreed or refused first; the outcome once the condition held",
        {
            "start": {(I_, P.REQUEST_WHEN): "asked"},
            "asked": {(R_, P.REFUSE): END, (R_, P.AGREE): "agreed"},
            "agreed": {(R_, P.FAILURE): END, (R_, P.INFORM): END},
        },
        "asked",
        "agreed",
    ),
    "fipa-subscribe": _r(
        "SC00035 §2: agreed or refused; informs until a failure or the initiator's cancel",
        {
            "start": {(I_, P.SUBSCRIBE): "asked"},
            "asked": {(R_, P.REFUSE): END, (R_, P.AGREE): "agreed"},
            "agreed": {(R_, P.INFORM): "agreed", (R_, P.FAILURE): END},
        },
        "asked",
        "agreed",
    ),
    "fipa-contract-net": _r(
        "SC00029 §2: one call for proposals; cancel at any point",
        _CONTRACT_NET,
        "called",
        "proposed",
        "accepted",
    ),
    "fipa-iterated-contract-net": _r(
        "SC00030 §2: as SC00029, and after the proposals the initiator may call again",
        {**_CONTRACT_NET, "proposed": {**_CONTRACT_NET["proposed"], (I_, P.CFP): "called"}},
        "called",
        "proposed",
        "accepted",
    ),
    "fipa-english-auction": _r(
        "SC00031 §2: start; rising calls; a bid accepted leads until outbid; the end; the "
        "winner asked to complete",
        {
            "start": {(I_, P.INFORM): "open"},
            "open": {(I_, P.CFP): "calling"},
            "calling": {(I_, P.CFP): "calling", (R_, P.PROPOSE): "bid", (I_, P.INFORM): END},
            "bid": {(I_, P.ACCEPT_PROPOSAL): "leads", (I_, P.REJECT_PROPOSAL): "calling"},
            "leads": {(I_, P.CFP): "leads", (I_, P.REJECT_PROPOSAL): "calling", (I_, P.INFORM): "won"},
            "won": {(I_, P.REQUEST): END},
        },
    ),
    "fipa-dutch-auction": _r(
        "SC00032 §2: start; falling calls; the first bid accepted, a later one rejected; the "
        "end; the winner asked to complete",
        {
            "start": {(I_, P.INFORM): "open"},
            "open": {(I_, P.CFP): "calling"},
            "calling": {(I_, P.CFP): "calling", (R_, P.PROPOSE): "bid", (I_, P.INFORM): END},
            "bid": {(I_, P.ACCEPT_PROPOSAL): "accepted", (I_, P.REJECT_PROPOSAL): "too-late"},
            "too-late": {(I_, P.INFORM): END},
            "accepted": {(I_, P.INFORM): "won"},
            "won": {(I_, P.REQUEST): END},
        },
    ),
    "fipa-brokering": _r("SC00033 §2", _PROXY, "asked", "agreed"),
    "fipa-recruiting": _r("SC00034 §2", _PROXY, "asked", "agreed"),
    "fipa-propose": _r(
        "SC00036 §2: accepted or rejected; no cancel",
        {
            "start": {(I_, P.PROPOSE): "proposed"},
            "proposed": {(R_, P.ACCEPT_PROPOSAL): END, (R_, P.REJECT_PROPOSAL): END},
        },
    ),
    "coordinate": _r(
        "paper §5.4, Figure 8: a plan requested; each L_SW report confirmed before the next; "
        "the confirm of a terminal report ends it; a_co's cancel asks a_ta to stop (a_ta "
        "reports on), and a confirm may come again while the plan runs",
        {
            "start": {(I_, P.REQUEST): "asked"},
            "asked": {
                (R_, P.REFUSE): END,
                (R_, P.FAILURE): END,
                (R_, P.INFORM, False): "reported",
                (R_, P.INFORM, True): "ending",
                (I_, P.CANCEL): "asked",
            },
            "reported": {(I_, P.CONFIRM): "running", (I_, P.CANCEL): "reported"},
            "running": {
                (R_, P.INFORM, False): "reported",
                (R_, P.INFORM, True): "ending",
                (I_, P.CONFIRM): "running",
                (I_, P.CANCEL): "running",
            },
            "ending": {(I_, P.CONFIRM): END},
        },
    ),
    "roco-notify": _r("inform, SC00037: one inform that nothing answers", {"start": {(I_, P.INFORM): END}}),
}
"""The second reading of each protocol."""

MACHINES = {**PROTOCOLS, **protocols_of(DEFAULT_SPEC)}
"""The protocols the runtime and verify follow: FIPA's library, and the shipped
specification's (its declared machines)."""


def _length(reading: Reading) -> int:
    """The longest path of the reading that repeats no state, plus two (a failed cancel counts
    its cancel and its answer)."""
    states = set(reading.steps) | {f"cancel:{s}" for s in reading.cancel_from}
    return min(len(states) + 1, 9) + 2


def legal_prefixes(reading: Reading) -> Iterator[tuple[tuple[Symbol, ...], frozenset[Where]]]:
    """Every sequence the reading allows up to its length, with where it leaves the
    conversation, shortest first."""
    level: list[tuple[tuple[Symbol, ...], frozenset[Where]]] = [((), frozenset({Where(reading.start)}))]
    symbols = reading.symbols()
    for _ in range(_length(reading)):
        yield from level
        level = [((*seq, s), nxt) for seq, at in level for s in symbols if (nxt := reading.after(at, s))]
    yield from level


class Followers:
    """The followers of one conversation: the runtime at each end and verify's observer."""

    def __init__(self, machine: Protocol) -> None:
        self.machine = machine
        self.ends = {INITIATOR: ProtocolStates(), PARTICIPANT: ProtocolStates()}
        self.observer = None
        self.latest: dict[str, str] = {}
        self.n = 0

    def take(self, symbol: Symbol) -> dict[str, bool]:
        """Each follower's verdict on one more communicate: True when allowed."""
        who, perf, terminal = symbol
        role: Role = INITIATOR if who == I_ else PARTICIPANT
        self.n += 1
        reply_with, in_reply_to = f"m{self.n}", self.latest.get(I_ if who == R_ else R_)
        verdicts = {}
        for end, table in self.ends.items():
            try:
                table.observe(
                    "peer", "c", self.machine, role, perf, local_role=end, terminal=terminal,
                    reply_with=reply_with, in_reply_to=in_reply_to,
                )  # fmt: skip
                verdicts[f"runtime at the {end}"] = True
            except (ProtocolViolation, ValueError):
                verdicts[f"runtime at the {end}"] = False
            table.commit()
        self.observer, _, refusal = judge(
            self.observer, self.machine, role, perf, terminal=terminal,
            reply_with=reply_with, in_reply_to=in_reply_to, copies=False,
        )  # fmt: skip
        verdicts["verify's follower"] = refusal is None
        self.latest[who] = reply_with
        return verdicts


FORGETFUL = "runtime at the initiator"
"""The one follower that never takes a conversation opened by a cancel: the initiator's own
runtime knows it did not open it (the other followers tolerate a cancel of a conversation
forgotten, services/runtime/protocol_state.py ``judge``)."""


FORGETTING = {"runtime at the initiator": I_, "runtime at the participant": R_}
"""An agent's runtime (by the party it is) takes a not-understood of a conversation it does not
know: one it forgot (ended long ago, or before a restart); it cannot tell it from one never
opened (services/runtime/protocol_state.py ``judge``)."""


def expected(follower: str, seq: tuple[Symbol, ...], allowed: bool) -> bool | None:
    """What ``follower`` must say of the last communicate of ``seq`` (the reading says
    ``allowed``); None: nothing (the initiator's runtime, which refused the first cancel, did not
    take the conversation up: what follows is another one for it)."""
    if follower == FORGETFUL and seq[0] == (I_, P.CANCEL, False):
        return False if len(seq) == 1 else None
    if seq[0][1] is P.NOT_UNDERSTOOD and follower in FORGETTING and seq[0][0] != FORGETTING[follower]:
        return True if len(seq) == 1 else None
    return allowed


def _follow(machine: Protocol, seq: tuple[Symbol, ...]) -> dict[str, bool]:
    """The followers' verdicts on the last communicate of ``seq``, after the others (each
    allowed by each follower that should: the prefix is legal)."""
    followers = Followers(machine)
    for n, symbol in enumerate(seq[:-1]):
        for who, ok in followers.take(symbol).items():
            assert expected(who, seq[: n + 1], True) in (ok, None), (who, seq, symbol)
    return followers.take(seq[-1])


def _show(seq: tuple[Symbol, ...]) -> str:
    return ", ".join(f"{w}:{p.value}{'[terminal]' if t else ''}" for w, p, t in seq)


OWN = ("coordinate", "roco-notify")
"""roco's own protocols, declared by the shipped specification. A protocol that a specification
grown since declares (docs/spec.md's walk-through adds one) has no reading here: whoever adds it
writes its machine, which tests/spec_check/test_declared_protocol.py checks."""


def test_every_protocol_followed_has_its_second_reading() -> None:
    assert set(READINGS) == {*PROTOCOLS, *OWN}, set(READINGS) ^ {*PROTOCOLS, *OWN}
    assert set(READINGS) <= set(MACHINES), set(READINGS) - set(MACHINES)


@pytest.mark.parametrize("name", sorted(READINGS))
def test_the_followers_agree_with_the_reading_on_every_sequence(name: str) -> None:
    reading, machine = READINGS[name], MACHINES[name]
    disagreements, tried = [], 0
    for seq, at in legal_prefixes(reading):
        if len(seq) >= _length(reading):
            continue
        for symbol in reading.symbols():
            allowed = bool(reading.after(at, symbol))
            verdicts = _follow(machine, (*seq, symbol))
            tried += 1
            wrong = [
                who
                for who, ok in verdicts.items()
                if expected(who, (*seq, symbol), allowed) not in (ok, None)
            ]
            if wrong:
                disagreements.append(
                    f"{_show((*seq, symbol))}: FIPA {'allows' if allowed else 'forbids'} it; not so {wrong}"
                )
    assert tried > 0
    assert not disagreements, f"{len(disagreements)} of {tried}:\n" + "\n".join(disagreements[:25])


SHIPPED = {
    "fipa-query": ("a_pl", "a_km"),
    "fipa-request": ("a_co", "a_pl"),
    "fipa-subscribe": ("a_km", "a_ta"),
    "coordinate": ("a_co", "a_ta"),
}
"""Protocols of the shipped specification, each with the initiator and the participant of one
channel carrying it (C4, C3, C6, C1)."""


PROTOCOL_KINDS = ("performative", "protocol-state", "conversation")
"""verify's violations that say the protocol was broken: a performative the sender's role never
sends in it, one its state does not allow, one that cannot belong to its conversation."""


def _record(run: Path, protocol: str, agents: tuple[str, str], seq: tuple[Symbol, ...]) -> Path:
    traffic: list[tuple[float, Communicate]] = []
    latest: dict[str, str] = {}
    for n, (who, perf, terminal) in enumerate(seq):
        sender, receiver = agents if who == I_ else agents[::-1]
        content, language = b"", None
        if terminal or (protocol == "coordinate" and perf is P.INFORM):
            from shared.fipa_codec.languages import encode_content
            from shared.fipa_codec.languages.l_sw import SWState, SWStatus

            state = SWState.SUCCEEDED if terminal else SWState.RUNNING
            language, content = encode_content(SWStatus(state=state, plan_id="p"))
        msg = Communicate(
            performative=perf,
            sender=AgentIdentifier(sender),
            receiver=(AgentIdentifier(receiver),),
            content=content,
            language=language,
            encoding="msgpack" if content else None,
            ontology="O_RoCo" if content else None,
            protocol=protocol,
            conversation_id="c",
            reply_with=f"m{n}",
            in_reply_to=latest.get(receiver),
        )
        latest[sender] = f"m{n}"
        traffic.append((0.01 * (n + 1), msg))
    return write_recorded_run(run, traffic)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_roco_spec_verify_agrees_with_the_reading_on_short_sequences(name: str, tmp_path: Path) -> None:
    """Each sequence of up to four communicates written as a run's record: verify's protocol
    verdict (its violations of :data:`PROTOCOL_KINDS`) is the reading's."""
    reading, spec = READINGS[name], default_spec()
    disagreements, tried = [], 0
    for n, (seq, at) in enumerate(legal_prefixes(reading)):
        if len(seq) >= 4:
            break
        for symbol in reading.symbols():
            allowed = bool(reading.after(at, symbol))
            run = _record(tmp_path / f"{n}-{tried}", name, SHIPPED[name], (*seq, symbol))
            report = verify_run(run, spec)
            flagged = [v for v in report.violations if v.kind in PROTOCOL_KINDS]
            tried += 1
            if bool(flagged) == allowed:
                says = "allows" if allowed else "forbids"
                disagreements.append(
                    f"{_show((*seq, symbol))}: FIPA {says} it; verify: {[v.text for v in flagged]}"
                )
    assert tried > 0
    assert not disagreements, f"{len(disagreements)} of {tried}:\n" + "\n".join(disagreements[:25])


def test_a_wrong_machine_is_caught_by_the_comparison() -> None:
    """The comparison can fail: fipa-contract-net's machine with iterated contract net's
    second cfp allowed (a planted fault) disagrees with the reading on that cfp."""
    machine = MACHINES["fipa-iterated-contract-net"]
    reading = READINGS["fipa-contract-net"]
    seq = ((I_, P.CFP, False), (R_, P.PROPOSE, False), (I_, P.CFP, False))
    at = frozenset({Where(reading.start)})
    for symbol in seq:
        at = reading.after(at, symbol)
    assert not at  # the reading forbids it …
    assert all(_follow(machine, seq).values())  # … the planted machine allows it everywhere
    # and a reading that forgot the cancel meta-protocol disagrees with the real machine
    bare = Reading("planted", READINGS["fipa-request"].steps)
    assert bare.after(frozenset({Where("asked", I_)}), (I_, P.CANCEL, False)) == frozenset()
    assert _follow(MACHINES["fipa-request"], ((I_, P.REQUEST, False), (I_, P.CANCEL, False)))[FORGETFUL]


def test_the_spec_loads() -> None:
    assert load(DEFAULT_SPEC).protocols
