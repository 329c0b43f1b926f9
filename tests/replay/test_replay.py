"""``roco replay`` on small records of a real agent (a_co answering "what are you doing?"):
what it reproduces, and each kind of difference it reports — a wrong reference, an identifier
used twice where the agent made two, a content term, a communicate sent in one and not the
other — plus the replays it refuses, and records a restarted recorder made (a communicate
twice, some recovered late, one missing). The pour's record is replayed in
tests/integration/test_pour_run.py; records made through the router and by a restarted
recorder in tests/integration/test_scenarios.py."""

from __future__ import annotations

import os
import re
from pathlib import Path

import msgspec
import pytest
from typer.testing import CliRunner

import services.cli as cli
from services.recorder.record import RawEntry
from services.replay.driver import ReplayError, render, replay
from services.report.load import load_run
from services.runtime.counters import CountersReport, save_counters
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages.l_ex import Observe
from shared.fipa_codec.languages.l_hc import Status, StatusQuery, TaskState, TaskStatus
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_wm import Subscription, WorldUpdate
from tests.support.messages import communicate
from tests.support.recorded_run import STARTED, answer_before_its_cause, rewrite_record, write_recorded_run


def _query(n: int) -> Communicate:
    return communicate(
        Performative.QUERY_REF,
        "a_hi",
        "a_co",
        "fipa-query",
        f"status-{n}",
        StatusQuery(),
        reply_with=f"a_hi-{n}",
        reply_by=1_800_000_000.0 + 30.0,
    )


def _answer(
    n: int, *, reply_with: str, in_reply_to: str | None = None, status: Status | None = None
) -> Communicate:
    return communicate(
        Performative.INFORM_REF,
        "a_co",
        "a_hi",
        "fipa-query",
        f"status-{n}",
        status or Status(tasks=()),
        reply_with=reply_with,
        in_reply_to=in_reply_to or f"a_hi-{n}",
    )


def _run(tmp_path: Path, *traffic: Communicate) -> Path:
    return write_recorded_run(tmp_path / "run", [(1.0 + 0.5 * i, m) for i, m in enumerate(traffic)])


def test_a_record_of_what_the_agent_does_is_reproduced(tmp_path: Path) -> None:
    run = _run(
        tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa"), _query(2), _answer(2, reply_with="a_co-bbbb")
    )
    result = replay(run, "a_co")
    assert result.equal, render(result)
    assert (result.inputs, result.compared) == (2, 2)
    assert render(result).endswith(f"({result.build_seconds:.2f} s to build a_co)")
    assert "2 compared; reproduced" in render(result)


def test_an_answer_to_the_wrong_request_is_a_difference(tmp_path: Path) -> None:
    """The record says a_co answered the second query in reply to the first: the replayed
    in-reply-to is a_hi's second reply-with, which the first already stands for."""
    wrong = _answer(2, reply_with="a_co-bbbb", in_reply_to="a_hi-1")
    run = _run(tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa"), _query(2), wrong)
    result = replay(run, "a_co")
    assert [(d.seq, d.field, d.recorded) for d in result.differences] == [(3, "in-reply-to", "a_hi-1")]
    assert result.differences[0].replayed == "a_hi-2 (where a_hi-1 was replayed as a_hi-1)"
    line = render(result).splitlines()[0]
    assert line.startswith(
        "#3 at   2.500 s a_co → a_hi inform-ref (fipa-query): in-reply-to: recorded a_hi-1"
    )


def test_one_identifier_where_the_replay_made_two_is_a_difference(tmp_path: Path) -> None:
    """Generated identifiers are paired, not ignored: a reply-with the record shows twice
    stands for the first replayed one only."""
    run = _run(
        tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa"), _query(2), _answer(2, reply_with="a_co-aaaa")
    )
    result = replay(run, "a_co")
    assert [(d.seq, d.field, d.recorded) for d in result.differences] == [(3, "reply-with", "a_co-aaaa")]
    assert "where a_co-aaaa was replayed as a_co-" in result.differences[0].replayed


def test_other_content_is_a_difference_named_by_its_path(tmp_path: Path) -> None:
    busy = Status(tasks=(TaskStatus(command_id="c1", text="pour", state=TaskState.RUNNING),))
    run = _run(tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa", status=busy))
    (d,) = replay(run, "a_co").differences
    assert (d.field, d.recorded, d.replayed) == ("content.tasks length", "1", "0")


def test_a_communicate_sent_in_one_and_not_the_other_is_a_difference(tmp_path: Path) -> None:
    unanswered = _run(tmp_path / "a", _query(1))
    (extra,) = replay(unanswered, "a_co").differences
    assert (extra.seq, extra.field, extra.recorded, extra.replayed) == (
        None,
        "communicate",
        "not sent",
        "sent",
    )
    twice = _run(
        tmp_path / "b", _query(1), _answer(1, reply_with="a_co-aaaa"), _answer(1, reply_with="a_co-cccc")
    )
    (missing,) = replay(twice, "a_co").differences
    assert (missing.seq, missing.field, missing.recorded, missing.replayed) == (
        2,
        "communicate",
        "sent",
        "not sent",
    )


def test_the_cli_exits_0_when_reproduced_and_1_with_one_line_per_difference(tmp_path: Path) -> None:
    run = _run(tmp_path / "same", _query(1), _answer(1, reply_with="a_co-aaaa"))
    done = CliRunner().invoke(cli.app, ["replay", str(run), "--agent", "a_co"], prog_name="roco")
    assert done.exit_code == 0, done.output
    assert "reproduced" in done.output.splitlines()[-1]
    other = _run(tmp_path / "other", _query(1), _answer(1, reply_with="a_co-aaaa", in_reply_to="a_hi-9"))
    done = CliRunner().invoke(cli.app, ["replay", str(other), "--agent", "a_co"], prog_name="roco")
    assert done.exit_code == 1
    lines = done.output.strip().splitlines()
    assert len(lines) == 2 and "in-reply-to: recorded a_hi-9, replayed a_hi-1" in lines[0]
    assert lines[1].startswith("roco: a_co replayed from") and "1 difference(s)" in lines[1]


def _observed(first: str) -> list[Communicate]:
    """a_ta's start as a_km subscribes: it agrees, asks ag_ex for an observation (L_EX Observe,
    3 s to answer) and passes ag_ex's answer on to a_km (L_WM WorldUpdate); ``first`` the
    answer recorded after what it answers (``after``) or before a_km's subscribe (``before``),
    as publishers linked directly can reach the recorder."""
    sub = communicate(
        Performative.SUBSCRIBE,
        "a_km",
        "a_ta",
        "fipa-subscribe",
        "km-env",
        Subscription(),
        reply_with="a_km-1",
    )
    agree = communicate(
        Performative.AGREE,
        "a_ta",
        "a_km",
        "fipa-subscribe",
        "km-env",
        reply_with="a_ta-1",
        in_reply_to="a_km-1",
    )
    ask = communicate(
        Performative.REQUEST, "a_ta", "ag_ex", "fipa-request", "c-1", Observe(), reply_with="a_ta-2"
    )
    ask = msgspec.structs.replace(ask, reply_by=STARTED + 1.0 + 3.0)
    seen = communicate(
        Performative.INFORM,
        "ag_ex",
        "a_ta",
        "fipa-request",
        "c-1",
        Observation(stamp=0.5, objects=()),
        reply_with="ag_ex-1",
        in_reply_to="a_ta-2",
    )
    update = communicate(
        Performative.INFORM,
        "a_ta",
        "a_km",
        "fipa-subscribe",
        "km-env",
        WorldUpdate(stamp=0.5, objects=(), total_particles=0),
        reply_with="a_ta-3",
        in_reply_to="a_km-1",
    )
    return [seen, sub, agree, ask, update] if first == "before" else [sub, agree, ask, seen, update]


def test_an_answer_recorded_before_the_question_is_fed_after_the_agent_asks(tmp_path: Path) -> None:
    """ag_ex's observation recorded before a_km's subscribe that made a_ta ask for it: in
    causal order a_ta reproduces as it does from the record in order; fed in the record's
    order (the causal ordering off), a_ta gets an answer to nothing and says not-understood."""
    # ag_ex's token never seen (a_ta would subscribe to its power-ons): only these conversations
    alive = ["a_km", "a_co"]
    in_order = write_recorded_run(tmp_path / "a", [(1.0, m) for m in _observed("after")], alive)
    assert replay(in_order, "a_ta").equal, render(replay(in_order, "a_ta"))
    crossed = write_recorded_run(tmp_path / "b", [(1.0, m) for m in _observed("before")], alive)
    result = replay(crossed, "a_ta")
    assert result.equal and (result.inputs, result.compared) == (2, 3), render(result)
    unordered = replay(crossed, "a_ta", causal=False)
    sent = [(d.field, d.replayed) for d in unordered.differences if d.recorded == "not sent"]
    assert ("communicate", "sent") in sent and unordered.counters["protocol_violations"] == 1, render(
        unordered
    )


@pytest.mark.parametrize("first", ["after", "before"])
def test_an_answer_is_put_before_its_cause_whatever_order_the_record_holds_them_in(
    tmp_path: Path, first: str
) -> None:
    """tests/support/recorded_run.py ``answer_before_its_cause`` (the pour's a_pl test builds its
    record with it) finds cause, question and answer by cause, not by the order of arrival: on a
    record where ag_ex's answer came after a_km's subscription that caused a_ta's question, and on
    one where it came before (the very order it builds), it builds the same order, and the
    replay takes the answer after a_ta asked."""
    alive = ["a_km", "a_co"]
    run = write_recorded_run(tmp_path / "run", [(1.0, m) for m in _observed(first)], alive)
    messages = load_run(run).messages
    order, cause, answer = answer_before_its_cause(messages, "a_km", "a_ta", "ag_ex")
    assert (cause.sender, answer.sender) == ("a_km", "ag_ex")
    assert [(m.sender, m.rec.performative) for m in order] == [
        ("ag_ex", "inform"),
        ("a_km", "subscribe"),
        ("a_ta", "agree"),
        ("a_ta", "request"),
        ("a_ta", "inform"),
    ]
    built = write_recorded_run(
        tmp_path / "built", [(1.0, m.comm) for m in order if m.comm is not None], alive
    )
    assert replay(built, "a_ta").equal


def test_roco_replay_without_an_agent_says_in_one_line_each_whether_it_reproduced(tmp_path: Path) -> None:
    """Each agent of the specification in turn: one line each, exit 0 when every agent that
    can be replayed reproduced, 1 when one differs (a mutated record output)."""
    run = _run(tmp_path / "same", _query(1), _answer(1, reply_with="a_co-aaaa"))
    done = CliRunner().invoke(cli.app, ["replay", str(run)], prog_name="roco")
    assert done.exit_code == 0, done.output
    lines = {line.partition(":")[0]: line for line in done.output.strip().splitlines()}
    assert lines["a_co"] == "a_co: reproduced, 1 inputs, 1 outputs"
    assert lines["a_pl"].startswith("a_pl: not replayed: ") and lines["a_hi"].startswith(
        "a_hi: not replayed: "
    )
    other = _run(tmp_path / "other", _query(1), _answer(1, reply_with="a_co-aaaa", in_reply_to="a_hi-9"))
    done = CliRunner().invoke(cli.app, ["replay", str(other)], prog_name="roco")
    assert done.exit_code == 1
    lines = {line.partition(":")[0]: line for line in done.output.strip().splitlines()}
    assert lines["a_co"].startswith("a_co: 1 difference: #1 at ")
    assert "in-reply-to: recorded a_hi-9, replayed a_hi-1" in lines["a_co"]


@pytest.mark.parametrize(
    ("agent", "says"),
    [
        ("a_hi", "a_hi takes input the traffic record does not hold (roco/human/in)"),
        ("a_xx", "no agent 'a_xx' in the specification"),
        ("a_pl", "holds no communicate to or from a_pl"),
    ],
)
def test_a_replay_that_cannot_be_made_is_one_line_and_exit_2(tmp_path: Path, agent: str, says: str) -> None:
    run = _run(tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa"))
    with pytest.raises(ReplayError, match=re.escape(says)):
        replay(run, agent)
    done = CliRunner().invoke(cli.app, ["replay", str(run), "--agent", agent], prog_name="roco")
    assert done.exit_code == 2
    (line,) = done.output.strip().splitlines()
    assert line.startswith("roco: ") and says in line


def test_the_replayed_agent_reads_neither_the_run_folder_nor_the_caller_s_state(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The run folder and the caller's settings stay as they were: a_co keeps its state in a
    folder of the replay's own, removed after."""
    state = tmp_path / "state"
    monkeypatch.setenv("ROCO_STATE_DIR", str(state))
    run = _run(tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa"))
    before = sorted(p.name for p in run.iterdir())
    assert replay(run, "a_co").equal
    assert sorted(p.name for p in run.iterdir()) == before and not state.exists()
    assert os.environ["ROCO_STATE_DIR"] == str(state)


def test_what_goes_wrong_inside_the_replayed_agent_is_reported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A handler that raises (the runtime counts it, answers failure and goes on): the answer
    differs and the agent's count says why; a step that raises outside a handler or a
    transition function stops the replay, and what it raised is reported."""
    from services.agents.coordinator.agent import Coordinator

    def broken(self: Coordinator) -> Status:
        raise RuntimeError("planted")

    run = _run(tmp_path, _query(1), _answer(1, reply_with="a_co-aaaa"))
    monkeypatch.setattr(Coordinator, "status", broken)
    result = replay(run, "a_co")
    found = {d.field: (d.recorded, d.replayed) for d in result.differences}
    assert found["performative"] == ("inform-ref", "failure")
    assert found["content"] == ("Status", "'internal error: RuntimeError: planted'")
    assert result.counters == {"handler_errors": 1}
    assert "the replayed a_co counted handler_errors 1; --log prints its log" in render(result)
    save_counters(run, {"a_co": CountersReport("a_co", 0.0, {"received.query-ref": 1})})
    assert "counted handler_errors 1 (0 in the run)" in render(replay(run, "a_co"))
    monkeypatch.setattr(Coordinator, "setup", broken)
    result = replay(run, "a_co")
    assert result.failure == "a_co raised at 1.000 s: RuntimeError: planted" and not result.equal
    assert (
        render(result)
        .splitlines()[-1]
        .endswith(f"then it failed in {result.seconds:.2f} s ({result.build_seconds:.2f} s to build a_co)")
    )


def _three(tmp_path: Path) -> Path:
    """a_hi asks a_co three times, a_co answers each (one publisher per key: a_hi's queries
    are sequence numbers 0, 1, 2 of one publisher)."""
    answers = ("a_co-aaaa", "a_co-bbbb", "a_co-cccc")
    return _run(
        tmp_path, *(m for n, r in enumerate(answers, 1) for m in (_query(n), _answer(n, reply_with=r)))
    )


def test_an_input_missing_from_the_record_is_said_instead_of_the_differences(tmp_path: Path) -> None:
    """a_hi's second query removed from the record (its publisher's sequence number 1 is not
    there): a_co cannot be reproduced, and its line says why, not the differences that follow
    from it; the whole replay still lists them."""
    run = rewrite_record(_three(tmp_path), lambda es: [e for e in es if e.seq != 2])
    result = replay(run, "a_co")
    assert result.missing == "1 input missing from the record" and not result.equal
    assert result.differences, render(result)  # the unasked answer, recorded but not sent
    done = CliRunner().invoke(cli.app, ["replay", str(run)], prog_name="roco")
    assert done.exit_code == 1
    lines = {line.partition(":")[0]: line for line in done.output.strip().splitlines()}
    assert lines["a_co"] == "a_co: cannot reproduce: 1 input missing from the record"
    last = render(result).splitlines()[-1]
    assert "; cannot reproduce: 1 input missing from the record (3 difference(s)) in " in last
    # an answer of a_co's removed instead: an output missing
    run = rewrite_record(_three(tmp_path / "out"), lambda es: [e for e in es if e.seq != 3])
    assert replay(run, "a_co").missing == "1 output missing from the record"


def _restarted(entries: list[RawEntry], at: int, twice: bool = True) -> list[RawEntry]:
    """``entries`` as a recorder restarted before entry ``at`` writes them: the first
    incarnation wrote those before, the next one the rest, the first of them recovered late
    from its publisher's cache, and (``twice``) the entry before ``at`` written again."""
    again = [RawEntry("test-2", len(entries), entries[at - 1].arrival)] if twice else []
    later = [RawEntry("test-2", e.seq, e.arrival) for e in entries[at:]]
    later[0] = RawEntry("test-2", later[0].seq, later[0].arrival._replace(late=True))
    return entries[:at] + again + later


def test_a_record_of_a_restarted_recorder_is_replayed_each_communicate_once(tmp_path: Path) -> None:
    """A record written by two recorder incarnations, a_hi's second query recorded by both:
    a_co is fed it once and reproduces; with one query lost as well, its line says when the
    recorder restarted."""
    whole = replay(_three(tmp_path / "a"), "a_co")
    run = rewrite_record(_three(tmp_path / "b"), lambda es: _restarted(es, 3))
    result = replay(run, "a_co")
    assert result.equal, render(result)
    assert (result.inputs, result.compared) == (whole.inputs, whole.compared) == (3, 3)
    assert "note: 1 communicate(s) of a_co recorded twice: taken once" in render(result)
    lost = rewrite_record(
        _three(tmp_path / "c"), lambda es: [e for e in _restarted(es, 3, False) if e.seq != 2]
    )
    # the second incarnation's first communicate not recovered late: the third query, at 3.000 s
    assert replay(lost, "a_co").missing == "1 input missing from the record (recorder restarted at 3.000 s)"
