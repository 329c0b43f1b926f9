"""Every kind of violation ``roco spec verify RUN`` reports (:data:`KINDS`) is seen failing.

A fault is planted in a copy of a recorded run (tests/spec_check/fixtures/urgent_mid_pour,
conformant as recorded): one communicate is sent again changed, or its answers are taken out of
the record. :func:`verify_run` reports the fault's kind on that communicate (its seq and its
conversation-id), and ``roco spec verify`` exits 1 naming the kind. A kind added to
:data:`KINDS` without a planted fault here fails
:func:`test_every_kind_of_violation_has_a_planted_fault`.

Each check behind a kind, deleted from a copy of services/spec_check/conformance.py (a
mutation check, one deletion at a time), fails the test of its fault and no other."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import pytest
from typer.testing import CliRunner

from services import cli
from services.recorder.presence import PresenceEvent, PresenceWriter
from services.recorder.record import RawEntry, record_of
from services.report.load import Message
from services.runtime import keys
from services.runtime.transport import Arrival
from services.spec.model import default_spec
from services.spec_check.conformance import KINDS, ConformanceReport, render, verify_run
from shared.fipa_codec import AgentIdentifier, Performative, decode, encode
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_wm import Answer
from tests.spec_check.recorded import URGENT, Pick, Recorded


def sent_again(
    r: Recorded, i: int, *, key: str | None = None, payload: bytes | None = None, **fields: Any
) -> Recorded:
    """``r`` with its ``i``-th communicate published again at the same time: with ``fields`` of
    the communicate changed (re-encoded), or as ``payload``; on ``key`` (default: its own). Its
    record is made again from what was published, as the recorder makes it
    (:func:`~services.recorder.record.record_of`)."""
    old = r.messages[i].rec
    if payload is None:
        payload = encode(msgspec.structs.replace(decode(r.payloads[i]), **fields))
    arrival = Arrival(old.t, key or old.key, payload, old.source, old.sn, old.t_sent, old.late, old.part)
    messages, payloads = list(r.messages), list(r.payloads)
    messages[i] = Message(record_of(RawEntry(old.incarnation, old.seq, arrival)), r.messages[i].t)
    payloads[i] = payload
    return Recorded(r.source, messages, payloads)


def on(channel: str, performative: str, sender: str | None = None) -> Pick:
    """The communicates of ``performative`` on ``channel`` (sent by ``sender``, when given)."""
    return lambda m: (
        m.rec.channel == channel and m.rec.performative == performative and sender in (None, m.rec.sender)
    )


@dataclass(frozen=True)
class Plant:
    """A fault planted on the first communicate that ``at`` picks: ``change`` makes the record
    with the fault from the recorded one and that communicate's index in it. The violation is
    expected on that communicate (at its seq, in the conversation it names once changed), its
    text saying ``says``: which of its kind's checks found it."""

    name: str
    at: Pick
    change: Callable[[Recorded, int], Recorded]
    says: str


def _without_answers(r: Recorded, i: int) -> Recorded:
    """``r`` without anything the receiver of its ``i``-th communicate sent in its conversation."""
    rec = r.messages[i].rec
    return r.remove(lambda m: m.rec.conversation_id == rec.conversation_id and m.rec.sender in rec.receivers)


_QUERY = on("C4", "query-ref", "a_pl")
_ANSWER = on("C4", "inform-ref", "a_km")
_AGREE = on("C2", "agree", "a_co")


PLANTED: dict[str, tuple[Plant, ...]] = {
    "malformed": (
        Plant(
            "a payload that is no communicate",
            _QUERY,
            lambda r, i: sent_again(r, i, payload=b"\x93not a communicate"),
            "the payload on roco/fipa/C4/a_pl/a_km is not a communicate",
        ),
    ),
    "key": (
        Plant(
            "a key naming another sender",
            _QUERY,
            lambda r, i: sent_again(r, i, key=keys.fipa_key("C4", "a_ta", "a_km")),
            "the key names sender a_ta, the communicate a_pl",
        ),
    ),
    "channel": (
        Plant(
            "a key on a channel that does not join the agents",
            _QUERY,
            lambda r, i: sent_again(r, i, key=keys.fipa_key("C6", "a_pl", "a_km")),
            "a_pl and a_km are joined by C4, not C6",
        ),
        Plant(
            "a receiver no channel joins the sender to",
            _QUERY,
            lambda r, i: sent_again(
                r, i, key=keys.fipa_key("C4", "a_pl", "a_hi"), receiver=(AgentIdentifier("a_hi"),)
            ),
            "no channel of the specification joins a_pl and a_hi",
        ),
    ),
    "performative": (
        Plant(
            "a performative the sender's role may not send",
            _ANSWER,
            lambda r, i: sent_again(r, i, performative=Performative.QUERY_REF),
            "the participant of fipa-query on C4 (a_km) may not send query-ref",
        ),
        Plant(
            "a protocol the channel does not carry",
            _QUERY,
            lambda r, i: sent_again(r, i, protocol="fipa-subscribe"),
            "protocol fipa-subscribe is not specified on C4",
        ),
    ),
    "language": (
        Plant(
            "content in another language",
            _QUERY,
            lambda r, i: sent_again(r, i, language="L_HFSM"),
            "must be in L_WM, not L_HFSM",
        ),
        Plant(
            "content in no language",
            _QUERY,
            lambda r, i: sent_again(r, i, language=None),
            "carries content but names no language",
        ),
    ),
    "ontology": (
        Plant(
            "the ontology of another language",
            _QUERY,
            lambda r, i: sent_again(r, i, ontology="O_Velma"),
            "language L_WM needs ontology O_RoCo, not O_Velma",
        ),
    ),
    "content": (
        Plant(
            "content that does not decode",
            _QUERY,
            lambda r, i: sent_again(r, i, content=b"\x91\x01"),
            "L_WM: ",
        ),
        Plant(
            "a term the specification does not list for the performative",
            _QUERY,
            lambda r, i: sent_again(r, i, content=encode_content(Answer())[1]),
            "query-ref in fipa-query on C4 carries a Answer",
        ),
    ),
    "protocol-state": (
        Plant(
            "an answer in a conversation of its own",
            _ANSWER,
            lambda r, i: sent_again(r, i, conversation_id="planted-answer"),
            "fipa-query: the participant may not send 'inform-ref' in state 'start'",
        ),
    ),
    "conversation": (
        Plant(
            "a communicate without conversation-id",
            _QUERY,
            lambda r, i: sent_again(r, i, conversation_id=None),
            "a fipa-query communicate without conversation-id",
        ),
        Plant(
            "an agree in another protocol than its conversation began with",
            _AGREE,
            lambda r, i: sent_again(r, i, protocol="fipa-subscribe"),
            "follows fipa-request, not fipa-subscribe",
        ),
    ),
    "unanswered": (
        Plant(
            "a subscribe whose participant never answers",
            on("C6", "subscribe", "a_km"),
            _without_answers,
            "a_ta never agreed to nor refused the subscribe",
        ),
    ),
}
"""The planted faults of each kind of violation."""

CASES = [(kind, plant) for kind, plants in PLANTED.items() for plant in plants]


def planted_run(plant: Plant, tmp_path: Path) -> tuple[Path, int, str | None]:
    """The recorded run with ``plant``'s fault, written under ``tmp_path``; the seq of the
    communicate it was planted on and the conversation-id it names (None: none)."""
    recorded = Recorded.read(URGENT)
    i = recorded.select(plant.at)[0]
    changed = plant.change(recorded, i)
    # the fixture's seqs, kept by sent_again and Recorded.remove, are renumbered by write
    original = recorded.messages[i].rec.seq
    (seq,) = [k for k, m in enumerate(changed.messages) if m.rec.seq == original]
    return changed.write(tmp_path / "run"), seq, changed.messages[seq].rec.conversation_id


def verify(run_dir: Path) -> ConformanceReport:
    return verify_run(run_dir, default_spec())


def test_every_kind_of_violation_has_a_planted_fault() -> None:
    assert set(PLANTED) == set(KINDS)
    assert all(PLANTED.values())


def test_the_recorded_run_conforms_in_full_as_recorded() -> None:
    report = verify(URGENT)
    assert report.full_conformance, render(report)
    assert report.violations == [] and report.unchecked == 0 and report.not_understood == []
    assert report.communicates == len(Recorded.read(URGENT).messages)
    result = CliRunner().invoke(cli.app, ["spec", "verify", str(URGENT)], prog_name="roco")
    assert result.exit_code == 0 and result.output.rstrip().endswith("full conformance: yes"), result.output


def test_the_recorded_run_written_back_unchanged_conforms_in_full(tmp_path: Path) -> None:
    """Recorded.write, which every planted fault goes through, changes nothing verify judges."""
    report = verify(Recorded.read(URGENT).write(tmp_path / "run"))
    assert report.full_conformance, render(report)


@pytest.mark.parametrize(("kind", "plant"), CASES, ids=[f"{k}: {p.name}" for k, p in CASES])
def test_a_planted_fault_is_reported_as_its_kind_on_the_planted_communicate(
    kind: str, plant: Plant, tmp_path: Path
) -> None:
    run_dir, seq, conversation = planted_run(plant, tmp_path)
    report = verify(run_dir)
    on_it = [v for v in report.violations if v.seq == seq]
    assert [(v.kind, v.conversation) for v in on_it] == [(kind, conversation)], render(report)
    assert plant.says in on_it[0].text, render(report)
    assert not report.full_conformance


@pytest.mark.parametrize("kind", list(PLANTED))
def test_roco_spec_verify_exits_1_naming_the_kind_of_a_planted_fault(kind: str, tmp_path: Path) -> None:
    run_dir, seq, _ = planted_run(PLANTED[kind][0], tmp_path)
    result = CliRunner().invoke(cli.app, ["spec", "verify", str(run_dir)], prog_name="roco")
    assert result.exit_code == 1, result.output
    lines = result.output.splitlines()
    assert any(line.startswith(f"  seq {seq} ") and f"[{kind}]" in line for line in lines), result.output
    assert result.output.rstrip().endswith("violation(s))")


def _a_ta_away(run_dir: Path, since: float, until: float) -> None:
    """A presence record in ``run_dir``: every agent there from the start, a_ta's token gone from
    ``since`` to ``until`` (POSIX s)."""
    start = Recorded.read(URGENT).messages[0].rec.t - 1
    there = [
        PresenceEvent(name=n, alive=True, t=start, seq=0, incarnation="r", snapshot=True)
        for n in default_spec().agent_names
    ]
    went = PresenceEvent(name="a_ta", alive=False, t=since, seq=0, incarnation="r")
    back = PresenceEvent(name="a_ta", alive=True, t=until, seq=0, incarnation="r")
    writer = PresenceWriter(run_dir)
    writer.write([*there, went, back])
    writer.close()


@pytest.mark.parametrize("gone", ["when it was sent", "before it answered"])
def test_a_subscribe_unanswered_because_its_receiver_was_away_is_lost_not_a_violation(
    gone: str, tmp_path: Path
) -> None:
    """The ``unanswered`` plant with a presence record that shows a_ta's process away when the
    subscribe was sent, or gone after it and before any answer: the put reached no process, so
    the conversation is listed as lost and the run conforms; a_ta away only after the record's
    end (the same plant, a presence record where it never left before) stays a violation."""
    plant = PLANTED["unanswered"][0]
    run_dir, seq, conversation = planted_run(plant, tmp_path)
    sent = Recorded.read(run_dir).messages[seq].rec
    t = sent.t_sent if sent.t_sent is not None else sent.t
    since = t - 0.5 if gone == "when it was sent" else t + 0.2
    _a_ta_away(run_dir, since, t + 3.0)
    report = verify(run_dir)
    assert report.full_conformance, render(report)
    (c,) = [c for c in report.conversations if c.conversation_id == conversation]
    assert not c.unanswered and c.lost.startswith("lost with a_ta's process: away") and gone in c.lost
    text = render(report)
    assert f"{conversation} a_km→a_ta fipa-subscribe" in text and "(lost with a_ta" in text


def test_a_subscribe_unanswered_by_a_receiver_that_stayed_is_a_violation_with_a_presence_record(
    tmp_path: Path,
) -> None:
    plant = PLANTED["unanswered"][0]
    run_dir, seq, _ = planted_run(plant, tmp_path)
    last = Recorded.read(run_dir).messages[-1].rec.t
    _a_ta_away(run_dir, last + 10, last + 20)  # away, but only after the record's end
    report = verify(run_dir)
    assert [v.kind for v in report.violations if v.seq == seq] == ["unanswered"], render(report)
