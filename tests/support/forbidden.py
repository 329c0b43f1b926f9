"""Conversations FIPA forbids (and legal ones), to append to a recorded run: what
tests/spec_check/test_forbidden_conversations.py and the live pour's test
(tests/integration/test_pour_run.py) plant in a real record for ``roco spec verify`` to flag.

Each conversation's communicates are cloned from the record's own (the first of each sender,
receiver and performative), so that channel, language and content are right and only the
protocol is wrong; each names the other party's latest in its in-reply-to (FIPA SC00026–SC00036
"Exceptions to IP Flow", SC00037 §3.12 not-understood, SC00061 conversation-id)."""

from __future__ import annotations

from pathlib import Path

import msgspec

from services.recorder.record import (
    TRAFFIC_RAW,
    RawEntry,
    TrafficRecord,
    encode_entry,
    read_entries,
    record_of,
)
from services.report.load import load_run
from services.runtime import keys
from services.runtime.run_folder import TRAFFIC_JSONL
from services.runtime.transport import Arrival
from services.spec.model import channel_between, default_spec
from shared.fipa_codec import Communicate, Performative, encode
from tests.support.recorded_run import copy_record

P = Performative
Template = tuple[str, str, Performative]
"""(sender, receiver, performative) of the recorded communicate a planted one is cloned from."""
Steps = list[tuple[Template, Performative]]

# templates: the first communicate of the record from sender to receiver with this performative
QUERY = ("a_pl", "a_km", P.QUERY_REF)
ANSWER = ("a_km", "a_pl", P.INFORM_REF)
PLAN_REQUEST = ("a_co", "a_pl", P.REQUEST)
PLAN = ("a_pl", "a_co", P.INFORM)
RUN_PLAN = ("a_co", "a_ta", P.REQUEST)
REPORT = ("a_ta", "a_co", P.INFORM)
CONFIRM = ("a_co", "a_ta", P.CONFIRM)

_NU = P.NOT_UNDERSTOOD
OPENS = "opens a conversation"
ENDED = "already ended"
ANSWERS = "not-understood answers a communicate received"

CASES: dict[str, tuple[str, list[tuple[tuple[str, str, Performative], Performative]], dict[int, str]]] = {
    # an initiator's not-understood to its own query, then three answers
    "not-understood from one who received nothing": (
        "fipa-query",
        [
            (QUERY, P.QUERY_REF),
            (QUERY, _NU),
            (ANSWER, P.INFORM_REF),
            (ANSWER, P.INFORM_REF),
            (ANSWER, P.INFORM_REF),
        ],
        {1: ANSWERS, 3: ENDED, 4: ENDED},
    ),
    "the same query three times, then one answer": (
        "fipa-query",
        [(QUERY, P.QUERY_REF), (QUERY, P.QUERY_REF), (QUERY, P.QUERY_REF), (ANSWER, P.INFORM_REF)],
        {1: OPENS, 2: OPENS},
    ),
    "a query answered, asked again and answered again": (
        "fipa-query",
        [(QUERY, P.QUERY_REF), (ANSWER, P.INFORM_REF), (QUERY, P.QUERY_REF), (ANSWER, P.INFORM_REF)],
        {2: OPENS, 3: ENDED},
    ),
    "a query-if answered by inform-ref": (
        "fipa-query",
        [(QUERY, P.QUERY_IF), (ANSWER, P.INFORM_REF)],
        {1: "may not send 'inform-ref'"},
    ),
    "a request whose result was sent, requested again": (
        "fipa-request",
        [(PLAN_REQUEST, P.REQUEST), (PLAN, P.INFORM), (PLAN_REQUEST, P.REQUEST), (PLAN, P.INFORM)],
        {2: OPENS, 3: ENDED},
    ),
    "a second plan inside one coordinate conversation": (
        "coordinate",
        [(RUN_PLAN, P.REQUEST), (REPORT, P.INFORM), (CONFIRM, P.CONFIRM), (RUN_PLAN, P.REQUEST)],
        {3: OPENS},
    ),
    # on a specification whose C3 carries the contract nets and the English auction as well
    "a second cfp in a contract net (iterated contract net's, SC00030)": (
        "fipa-contract-net",
        [
            (PLAN_REQUEST, P.CFP),
            (PLAN, P.PROPOSE),
            (PLAN_REQUEST, P.CFP),
            (PLAN, P.PROPOSE),
            (PLAN_REQUEST, P.ACCEPT_PROPOSAL),
            (PLAN, P.INFORM),
        ],
        {2: "may not send 'cfp'", 3: "may not send 'propose'"},
    ),
    "a second start of an English auction": (
        "fipa-english-auction",
        [(PLAN_REQUEST, P.INFORM), (PLAN_REQUEST, P.CFP), (PLAN, P.PROPOSE), (PLAN_REQUEST, P.INFORM)],
        {3: "may not send 'inform'"},
    ),
}
"""Each forbidden conversation: its protocol, its communicates (template, performative) and
what verify must flag (index → words of the rule)."""

LEGAL: dict[str, tuple[str, list[tuple[tuple[str, str, Performative], Performative]]]] = {
    "a query answered": ("fipa-query", [(QUERY, P.QUERY_REF), (ANSWER, P.INFORM_REF)]),
    "a not-understood of an answer": (
        "fipa-query",
        [(QUERY, P.QUERY_REF), (ANSWER, P.INFORM_REF), (QUERY, _NU)],
    ),
    "an iterated contract net with a second cfp": (
        "fipa-iterated-contract-net",
        [
            (PLAN_REQUEST, P.CFP),
            (PLAN, P.PROPOSE),
            (PLAN_REQUEST, P.CFP),
            (PLAN, P.PROPOSE),
            (PLAN_REQUEST, P.ACCEPT_PROPOSAL),
            (PLAN, P.INFORM),
        ],
    ),
    "a contract net cancelled before any proposal": (
        "fipa-contract-net",
        [(PLAN_REQUEST, P.CFP), (PLAN_REQUEST, P.CANCEL), (PLAN, P.INFORM)],
    ),
}
"""Legal extra conversations: verify keeps its yes."""

EXTRA = ("fipa-contract-net", "fipa-iterated-contract-net", "fipa-english-auction")
"""Protocols no channel of the shipped specification carries (their cases need a copy that does)."""


def templates(run: Path) -> dict[Template, Communicate]:
    """The first communicate of each (sender, receiver, performative) in ``run``'s record."""
    found: dict[Template, Communicate] = {}
    for m in load_run(run).messages:
        if m.comm is not None and m.comm.sender is not None and m.comm.receiver:
            found.setdefault((m.comm.sender.name, m.comm.receiver[0].name, m.comm.performative), m.comm)
    return found


def planted(run: Path, cid: str, protocol: str, steps: Steps) -> list[Communicate]:
    """The communicates of conversation ``cid`` of ``steps``, each cloned from its template in
    ``run`` with the performative, conversation-id and protocol given, its reply-with fresh and
    its in-reply-to the other side's latest (a not-understood's content a reason in text)."""
    base_of = templates(run)
    latest: dict[str, str] = {}
    out = []
    for n, (template, perf) in enumerate(steps):
        sender, receiver, _ = template
        base = base_of[template]
        reply_with = f"{cid}-{n}"
        content, language, encoding = base.content, base.language, base.encoding
        if perf is P.NOT_UNDERSTOOD:
            content, language, encoding = b"planted: not understood", None, "utf-8"
        out.append(
            msgspec.structs.replace(
                base,
                performative=perf,
                protocol=protocol,
                conversation_id=cid,
                reply_with=reply_with,
                in_reply_to=latest.get(receiver),
                reply_by=None,
                content=content,
                language=language,
                encoding=encoding,
                ontology=base.ontology if language is not None else None,
            )
        )
        latest[sender] = reply_with
    return out


def append_conversation(run: Path, dest: Path, cid: str, protocol: str, steps: Steps) -> Path:
    """``dest``: a copy of ``run``'s record with the conversation ``cid`` of ``steps``
    (:func:`planted`) after it, 10 ms apart, written as the record was (raw entries of the
    recorder, or the ``[seq, payload]`` pairs of an older record)."""
    comms = planted(run, cid, protocol, steps)
    out = copy_record(run, dest)
    records = [msgspec.json.decode(line) for line in (out / TRAFFIC_JSONL).read_bytes().splitlines()]
    raw = [e for e, _, _, _ in read_entries(out)]
    seq, t = records[-1]["seq"], records[-1]["t"]
    lines, chunks = [], []
    sent: dict[str, int] = {}  # the planted publishers' sequence numbers, per key
    for comm in comms:
        assert comm.sender is not None
        sender, receiver = comm.sender.name, comm.receiver[0].name
        channel = channel_between(default_spec(), sender, receiver)
        assert channel is not None
        key, payload = keys.fipa_key(channel.name, sender, receiver), encode(comm)
        seq, t = seq + 1, t + 0.01
        if raw and raw[-1] is not None:
            sent[key] = sn = sent.get(key, -1) + 1
            entry = RawEntry(raw[-1].incarnation, seq, Arrival(t, key, payload, f"planted:{key}", sn, t))
            lines.append(msgspec.json.encode(record_of(entry)) + b"\n")
            chunks.append(encode_entry(entry))
            continue
        record = TrafficRecord(
            seq=seq,
            t=t,
            size=len(payload),
            channel=channel.name,
            sender=sender,
            receivers=(receiver,),
            performative=comm.performative.value,
            protocol=protocol,
            conversation_id=cid,
            language=comm.language,
            ontology=comm.ontology,
            key=key,
            t_sent=t,
            key_sender=sender,
        )
        lines.append(msgspec.json.encode(record) + b"\n")
        chunks.append(msgspec.msgpack.encode([seq, payload]))
    with (out / TRAFFIC_JSONL).open("ab") as f:
        f.write(b"".join(lines))
    with (out / TRAFFIC_RAW).open("ab") as f:
        f.write(b"".join(chunks))
    return out
