"""Malformed communicates for fuzzing an agent's inbox and the codec.

Every strategy draws a :class:`Fuzz`: the Zenoh key it is put on (``roco/fipa/C/S/R`` with a
sender S that legitimately talks to R on channel C, as an impostor or a buggy peer would),
the payload, and the reason (``rejected.<reason>`` counter, services/runtime/limits.py) the
receiving agent must reject it for. Kinds:

- ``random``: random bytes; ``truncated``: a valid encoding cut short;
- ``wrong_type``: a msgpack map with a field of the wrong type; ``unknown_performative``;
- ``bad_content``: content that does not decode in its language (random bytes, or a term
  of another language); ``nested``: an L_HFSM plan nested far deeper than the stack;
- ``wrong_state``: a valid communicate that does not open a conversation, in a conversation
  the agent does not know (a reply to nothing);
- ``sender_mismatch``: the sender parameter is not the sender in the key;
- ``not_in_interface``: a performative the specification does not let S send R;
- ``oversized`` (:func:`oversized`, not drawn: 4 MiB each).

None of them may be acted on: the fuzzer never sends a communicate an agent would execute.
"""

from __future__ import annotations

import random
import uuid
from dataclasses import dataclass
from functools import cache

import msgspec
from hypothesis import strategies as st

from services.runtime import keys
from services.runtime.protocol_state import CrossingTracker, expected_ontology
from services.spec.model import MessageKind, default_spec, interface
from services.spec.protocol_defs import machine_of
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, encode
from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES
from shared.fipa_codec.languages import encode_content, load_all
from shared.fipa_codec.languages.l_wm import ObjectQuery
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT

AGENTS = ("a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex")
_mp = msgspec.msgpack.Encoder()


@dataclass(frozen=True)
class Fuzz:
    """One malformed communicate: ``key`` and ``payload`` as put on Zenoh, ``kind`` of
    malformation, ``reason`` the agent must count it under, ``cid`` the conversation-id its
    not-understood carries (None when the payload does not decode)."""

    kind: str
    key: str
    payload: bytes
    reason: str
    cid: str | None = None

    @property
    def sender(self) -> str:
        return keys.parse_fipa_key(self.key).sender


@cache
def receivable(agent: str) -> tuple[MessageKind, ...]:
    """The kinds of communicate ``agent`` may receive (its interface), not-understood and
    cancel left out (a not-understood is never answered; a cancel of an unknown conversation
    is answered as a late cancel, not rejected)."""
    out = [
        k
        for k in interface(default_spec(), agent).receives
        if k.performative not in ("not-understood", "cancel")
    ]
    return tuple(out)


def _is_opener(kind: MessageKind) -> bool:
    spec = default_spec()
    channel = next(c for c in spec.channels if c.name == kind.channel)
    cp = next(p for p in channel.protocols if p.protocol == kind.protocol)
    role = INITIATOR if cp.initiator == kind.sender else PARTICIPANT
    try:  # the machine the specification declares (coordinate) or names (FIPA's)
        return CrossingTracker(machine_of(spec, kind.protocol)).is_opener(role, kind.performative)
    except ValueError:  # a protocol without a state machine (SpecError is one)
        return True


def _cid() -> str:
    return f"fuzz-{uuid.uuid4().hex[:12]}"


def _msg(kind: MessageKind, **fields: object) -> Communicate:
    base: dict[str, object] = dict(
        performative=Performative(kind.performative),
        sender=AgentIdentifier(kind.sender),
        receiver=(AgentIdentifier(kind.receiver),),
        protocol=kind.protocol,
        conversation_id=_cid(),
        reply_with=f"rw-{uuid.uuid4().hex[:8]}",
    )
    base.update(fields)
    return Communicate(**base)  # type: ignore[arg-type]


def _key(kind: MessageKind) -> str:
    return keys.fipa_key(kind.channel, kind.sender, kind.receiver)


def kinds_for(agent: str) -> st.SearchStrategy[MessageKind]:
    return st.sampled_from(receivable(agent))


@st.composite
def random_bytes(draw: st.DrawFn, agent: str) -> Fuzz:
    kind = draw(kinds_for(agent))
    return Fuzz("random", _key(kind), draw(st.binary(max_size=256)), "malformed")


@st.composite
def truncated(draw: st.DrawFn, agent: str) -> Fuzz:
    kind = draw(kinds_for(agent))
    lang, body = encode_content(ObjectQuery("jar"))
    data = encode(_msg(kind, content=body, language=lang, encoding="msgpack", ontology="O_RoCo"))
    cut = draw(st.integers(0, len(data) - 1))
    return Fuzz("truncated", _key(kind), data[:cut], "malformed")


_WRONG_FIELDS = {
    "performative": st.integers(-(2**63), 2**64 - 1) | st.none() | st.binary(max_size=8),
    "sender": st.integers(-(2**63), 2**64 - 1) | st.text(max_size=8) | st.just(["", [], [], []]),
    "receiver": st.text(max_size=8) | st.integers(0, 9),
    "content": st.integers(-(2**63), 2**64 - 1) | st.lists(st.integers(0, 9), max_size=3),
    "language": st.integers(-(2**63), 2**64 - 1) | st.binary(max_size=4),
    "protocol": st.integers(-(2**63), 2**64 - 1) | st.lists(st.text(max_size=3), max_size=2),
    "conversation-id": st.integers(-(2**63), 2**64 - 1) | st.floats(),
    "reply-by": st.text(max_size=8) | st.binary(max_size=4),
    "user-params": st.dictionaries(
        st.text(max_size=5).filter(lambda k: not k.startswith(("X-", "x-"))),
        st.text(),
        min_size=1,
        max_size=2,
    )
    | st.integers(0, 9),
}


@st.composite
def wrong_type(draw: st.DrawFn, agent: str) -> Fuzz:
    kind = draw(kinds_for(agent))
    fields: dict[str, object] = {
        "performative": kind.performative,
        "sender": [kind.sender, [], [], []],
        "receiver": [[kind.receiver, [], [], []]],
        "protocol": kind.protocol,
        "conversation-id": _cid(),
    }
    name = draw(st.sampled_from(sorted(_WRONG_FIELDS)))
    fields[name] = draw(_WRONG_FIELDS[name])
    return Fuzz("wrong_type", _key(kind), _mp.encode(fields), "malformed")


@st.composite
def unknown_performative(draw: st.DrawFn, agent: str) -> Fuzz:
    kind = draw(kinds_for(agent))
    name = draw(st.text(max_size=20).filter(lambda t: t not in {p.value for p in Performative}))
    fields = {
        "performative": name,
        "sender": [kind.sender],
        "protocol": kind.protocol,
        "conversation-id": _cid(),
    }
    return Fuzz("unknown_performative", _key(kind), _mp.encode(fields), "malformed")


def _nested_plan(depth: int) -> bytes:
    """An L_HFSM ``plan`` whose root PlanNode nests ``depth`` levels of children."""
    head = b"".join(
        b"\x82" + _mp.encode("name") + _mp.encode("n") + _mp.encode("children") + b"\x91"
        for _ in range(depth)
    )
    root = head + b"\x81" + _mp.encode("name") + _mp.encode("leaf")
    return (
        b"\x84"
        + b"".join(_mp.encode(x) for x in ("type", "plan", "plan_id", "p", "task_id", "t", "root"))
        + root
    )


@st.composite
def bad_content(draw: st.DrawFn, agent: str) -> Fuzz:
    choices = [k for k in receivable(agent) if k.languages]
    kind = draw(st.sampled_from(choices))
    language = draw(st.sampled_from(kind.languages))
    other = [n for n in load_all() if n != language]
    how = draw(st.sampled_from(["random", "other_language", "nested", "empty_map"]))
    if how == "random":
        body = draw(st.binary(min_size=1, max_size=128))
    elif how == "other_language":
        body = encode_content(_sample_term(draw(st.sampled_from(other))))[1]
    elif how == "nested":
        body = _nested_plan(draw(st.integers(1500, 20000)))
    else:
        body = b"\x80"
    cid = _cid()
    msg = _msg(
        kind,
        content=body,
        language=language,
        encoding="msgpack",
        ontology=expected_ontology(language),
        conversation_id=cid,
    )
    return Fuzz("nested" if how == "nested" else "bad_content", _key(kind), encode(msg), "content", cid)


def _sample_term(language: str) -> msgspec.Struct:
    from shared.fipa_codec.languages import language_of
    from tests.fipa_codec.fipa_strategies import SAMPLE_TERMS

    return next(t for t in SAMPLE_TERMS if language_of(t).name == language)


@st.composite
def wrong_state(draw: st.DrawFn, agent: str) -> Fuzz:
    choices = [k for k in receivable(agent) if not _is_opener(k)]
    if not choices:  # ag_ex receives only openers (request): nothing can be out of state
        return draw(not_in_interface(agent))
    kind = draw(st.sampled_from(choices))
    cid = _cid()
    msg = _msg(kind, conversation_id=cid, in_reply_to=f"nothing-{uuid.uuid4().hex[:6]}")
    return Fuzz("wrong_state", _key(kind), encode(msg), "protocol_state", cid)


@st.composite
def sender_mismatch(draw: st.DrawFn, agent: str) -> Fuzz:
    kind = draw(kinds_for(agent))
    other = draw(st.sampled_from([a for a in AGENTS if a != kind.sender]))
    cid = _cid()
    msg = _msg(kind, sender=AgentIdentifier(other), conversation_id=cid)
    return Fuzz("sender_mismatch", _key(kind), encode(msg), "sender_mismatch", cid)


@st.composite
def not_in_interface(draw: st.DrawFn, agent: str) -> Fuzz:
    kind = draw(kinds_for(agent))
    allowed = {
        k.performative for k in receivable(agent) if k.sender == kind.sender and k.protocol == kind.protocol
    }
    perf = draw(
        st.sampled_from([p for p in Performative if p.value not in allowed | {"not-understood", "cancel"}])
    )
    protocol = draw(st.sampled_from([kind.protocol, "fipa-bogus", "fipa-contract-net"]))
    cid = _cid()
    msg = _msg(kind, performative=perf, protocol=protocol, conversation_id=cid)
    return Fuzz("not_in_interface", _key(kind), encode(msg), "not_in_interface", cid)


def malformed(agent: str) -> st.SearchStrategy[Fuzz]:
    """Any of the drawn kinds of malformed communicate for ``agent``."""
    return st.one_of(
        random_bytes(agent),
        truncated(agent),
        wrong_type(agent),
        unknown_performative(agent),
        bad_content(agent),
        wrong_state(agent),
        sender_mismatch(agent),
        not_in_interface(agent),
    )


def oversized(agent: str, extra: int = 1) -> Fuzz:
    """A communicate ``extra`` bytes over the limit (a valid one, padded in its content)."""
    kind = receivable(agent)[0]
    msg = _msg(kind, content=b"", conversation_id=_cid())
    size = len(encode(msg))
    padded = _msg(
        kind, content=b"x" * (MAX_COMMUNICATE_BYTES - size + extra), conversation_id=msg.conversation_id
    )
    data = encode(padded, max_size=2 * MAX_COMMUNICATE_BYTES)
    assert len(data) > MAX_COMMUNICATE_BYTES
    return Fuzz("oversized", _key(kind), data, "oversized")


# ---------------------------------------------------------------------------------------------
# Without Hypothesis: a fast stream of malformed communicates for floods (a fuzzer process
# during a live pour sends tens of thousands of them).

_FLOOD_KINDS = (
    "random",
    "truncated",
    "wrong_type",
    "unknown_performative",
    "bad_content",
    "nested",
    "wrong_state",
    "sender_mismatch",
    "not_in_interface",
)


def targets(sender: str) -> tuple[str, ...]:
    """The agents ``sender`` may send to (its channels' other ends), in AGENTS order: what an
    attacker holding ``sender``'s credentials can reach through a router with access control."""
    return tuple(a for a in AGENTS if a != sender and any(k.sender == sender for k in receivable(a)))


def flood(agent: str, rng: random.Random, sender: str | None = None) -> Fuzz:
    """One malformed communicate for ``agent`` drawn with ``rng``; never a byte-identical copy
    of an earlier one (each carries a fresh conversation-id or random bytes), so each must
    be answered. ``sender``: only on keys of that sender (a compromised agent's identity, whose
    keys are all the router lets it put on); None: any of ``agent``'s peers. Raises ValueError
    when ``sender`` may not send to ``agent``."""
    kinds = receivable(agent)
    if sender is not None:
        kinds = tuple(k for k in kinds if k.sender == sender)
        if not kinds:
            raise ValueError(f"{sender} sends nothing to {agent}")
    kind = rng.choice(kinds)
    what = rng.choice(_FLOOD_KINDS)
    if what == "random":
        return Fuzz(what, _key(kind), rng.randbytes(rng.randrange(1, 200)) + b"\xc1", "malformed")
    if what == "truncated":
        data = encode(_msg(kind))
        return Fuzz(what, _key(kind), data[: rng.randrange(1, len(data) - 1)], "malformed")
    if what == "wrong_type":
        wrong: dict[str, object] = {
            "performative": rng.choice([12345, [1, 2], None]),
            "sender": rng.choice([12345, {"x": 1}]),
            "receiver": rng.choice([12345, "a_km"]),
            "content": rng.choice([12345, [1, 2]]),
            "reply-by": rng.choice(["soon", [1.5]]),
            "protocol": rng.choice([12345, [1, 2]]),
        }
        field = rng.choice(sorted(wrong))
        bad: dict[str, object] = {
            "performative": kind.performative,
            "sender": [kind.sender],
            "protocol": kind.protocol,
            field: wrong[field],
        }
        bad["conversation-id"] = _cid()
        return Fuzz(what, _key(kind), _mp.encode(bad), "malformed")
    if what == "unknown_performative":
        bad = {
            "performative": f"shout-{rng.randrange(10**9)}",
            "sender": [kind.sender],
            "protocol": kind.protocol,
        }
        return Fuzz(what, _key(kind), _mp.encode(bad), "malformed")
    if what in ("bad_content", "nested") and not any(k.languages for k in kinds):
        what = "not_in_interface"
    if what in ("bad_content", "nested"):
        with_language = [k for k in kinds if k.languages]
        kind = rng.choice(with_language)
        language = rng.choice(kind.languages)
        body = (
            _nested_plan(rng.randrange(1500, 4000))
            if what == "nested"
            else rng.randbytes(rng.randrange(1, 64))
        )
        cid = _cid()
        msg = _msg(
            kind,
            content=body,
            language=language,
            encoding="msgpack",
            ontology=expected_ontology(language),
            conversation_id=cid,
        )
        return Fuzz(what, _key(kind), encode(msg), "content", cid)
    if what == "wrong_state":
        late = [k for k in kinds if not _is_opener(k)]
        if late:
            kind = rng.choice(late)
            cid = _cid()
            return Fuzz(what, _key(kind), encode(_msg(kind, conversation_id=cid)), "protocol_state", cid)
        what = "not_in_interface"
    if what == "sender_mismatch":
        cid = _cid()
        other = rng.choice([a for a in AGENTS if a != kind.sender])
        msg = _msg(kind, sender=AgentIdentifier(other), conversation_id=cid)
        return Fuzz(what, _key(kind), encode(msg), "sender_mismatch", cid)
    cid = _cid()
    msg = _msg(kind, performative=Performative.PROPAGATE, conversation_id=cid)
    return Fuzz("not_in_interface", _key(kind), encode(msg), "not_in_interface", cid)
