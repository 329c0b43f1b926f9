"""`roco chaos`'s "nothing executed twice" asks ag_ex's ledger too (velma/executor/ledger.py,
services/report/ledger.py): each fault is planted in a mutated ledger beside a synthetic record
(a real fleet's ledger: tests/integration/test_planted_faults_run.py)."""

from __future__ import annotations

from pathlib import Path

from services.report.ledger import judge_ledger
from services.report.load import load_run
from services.runtime.human import HumanReport, ReportKind
from services.runtime.run_folder import RunInfo, write_run_info
from services.scenario.chaos import chaos_scenario, verdict, write_chaos_report
from services.scenario.runner import CommandRecord, ScenarioOutcome
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import HALTED, CommandResult
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from tests.report.conftest import STARTED, RunBuilder, write_traffic
from tests.support.ledger import ran
from velma.executor.ledger import INTERRUPTED, LEDGER_FILE, MAX_LINE_BYTES, Ledger, read_ledger

SCENE = Observation(
    stamp=3.1,
    objects=tuple(ObjectObservation(name=n, pose=Pose((0.3, -0.5, 0.77))) for n in ("jar", "bowl", "cup")),
)


def _outcome() -> ScenarioOutcome:
    record = CommandRecord(1, "pour the jar into the bowl", "r1")
    record.final = HumanReport(request_id="r1", kind=ReportKind.SUCCEEDED, text="")
    return ScenarioOutcome([record], "", [])


def _run(tmp_path: Path) -> Path:
    """A run whose record has ag_ex answer c1 (a grasp, ok), c2 (an observation) and c3's
    cancel (halted); its ledger holds the three runs, each started and ended once."""
    b = RunBuilder()
    answers = [
        ("c1", CommandResult(command="grasp", ok=True, sim_time=2.0)),
        ("c2", SCENE),
        ("c3", CommandResult(command="move_tool", ok=False, reason=HALTED, sim_time=5.0)),
    ]
    for k, (conversation, content) in enumerate(answers):
        b.add(2 * k + 1, "C5", "a_ta", "ag_ex", "request", protocol="fipa-request", conversation=conversation)
        b.add(
            2 * k + 2,
            "C5",
            "ag_ex",
            "a_ta",
            "inform",
            content,
            protocol="fipa-request",
            conversation=conversation,
        )
    d = tmp_path / "run"
    (d / "logs").mkdir(parents=True)
    write_run_info(d, RunInfo(started=STARTED))
    write_traffic(d, b)
    ran(d, ("c1", "grasp", 1.0, 2.0), ("c2", "observe", 3.0, 3.1), ("c3", "move_tool", 4.0, 5.0))
    return d


def _lines(run: Path) -> list[str]:
    return (run / LEDGER_FILE).read_text().splitlines(keepends=True)


def test_a_ledger_that_agrees_with_the_record_passes(tmp_path: Path) -> None:
    run = _run(tmp_path)
    v = verdict(run, _outcome())
    assert v.ok and v.ledger.ok and v.ledger.found and v.ledger.runs == 3 and v.ledger.lives == 1
    text = write_chaos_report(run, chaos_scenario(0), _outcome(), v).read_text()
    assert (
        "| nothing executed twice | yes ag_ex's ledger: 3 command(s) started by 1 ag_ex process(es): "
        "nothing executed twice, every done answer ran |"
    ) in text


def test_a_command_started_twice_with_one_answer_fails_the_question(tmp_path: Path) -> None:
    """Planted: the grasp's start and end written again, as when the loop ran it twice."""
    run = _run(tmp_path)
    lines = _lines(run)
    (run / LEDGER_FILE).write_text("".join(lines[:2] + lines[:2] + lines[2:]))
    v = verdict(run, _outcome())
    assert v.executed_twice == []  # one answer: the record alone cannot tell
    assert not v.ok and v.ledger.twice == ["grasp (c1): started at 1.000, 1.000 s"]
    text = write_chaos_report(run, chaos_scenario(0), _outcome(), v).read_text()
    assert "| nothing executed twice | **no** ag_ex's ledger: " in text
    assert "executed twice: grasp (c1): started at 1.000, 1.000 s" in text


def test_a_run_that_ended_and_ran_again_in_a_restarted_ag_ex_was_executed_twice(tmp_path: Path) -> None:
    """Planted: a restarted ag_ex ran c1 again after the first one had ended it (a request
    sent again after a restart that the first ag_ex had carried out but not answered)."""
    run = _run(tmp_path)
    ran(run, ("c1", "grasp", 6.0, 7.0), life="200-bbbbbb")
    v = judge_ledger(run, load_run(run).messages)
    assert not v.ok and v.lives == 2 and v.twice == ["grasp (c1): started at 1.000, 6.000 s"]


def test_a_run_interrupted_by_a_restart_and_run_again_is_resumed_not_twice(tmp_path: Path) -> None:
    """a_ta sends a request again to a restarted ag_ex: the first ag_ex stopped under it
    (no end, or the stopping loop's ``failure: stopped``), so the second run is the only one
    that ended; the same in one ag_ex would be executed twice."""
    run = _run(tmp_path)
    lines = _lines(run)
    (run / LEDGER_FILE).write_text("".join(lines[:1] + lines[2:]))  # c1 started, never ended
    ran(run, ("c1", "grasp", 6.0, 7.0), life="200-bbbbbb")
    v = judge_ledger(run, load_run(run).messages)
    assert v.ok and v.resumed == ["grasp (c1): started at 1.000, 6.000 s"]
    assert "resumed after a restart: grasp (c1)" in v.summary()
    ledger = Ledger(run / LEDGER_FILE, life="200-bbbbbb")
    ledger.started("c3", "move_tool", 8.0)
    ledger.ended("c3", "move_tool", 8.5, INTERRUPTED)
    ledger.started("c3", "move_tool", 9.0)  # the same ag_ex again: twice
    ledger.close()
    v = judge_ledger(run, load_run(run).messages)
    assert v.twice == ["move_tool (c3): started at 4.000, 8.000, 9.000 s"]


def test_a_command_answered_done_that_never_ran_fails_the_question(tmp_path: Path) -> None:
    """Planted: the observation's ledger lines removed; then its end alone; then no ledger."""
    run = _run(tmp_path)
    lines = _lines(run)
    (run / LEDGER_FILE).write_text("".join(lines[:2] + lines[4:]))
    v = verdict(run, _outcome())
    assert not v.ok and v.ledger.never_ran == ["observe (c2)"] and not v.ledger.twice
    text = write_chaos_report(run, chaos_scenario(0), _outcome(), v).read_text()
    assert "| nothing executed twice | **no** " in text and "answered done, never ran: observe (c2)" in text
    (run / LEDGER_FILE).write_text("".join(lines[:3] + lines[4:]))  # started, never ended
    assert judge_ledger(run, load_run(run).messages).never_ran == ["observe (c2)"]
    (run / LEDGER_FILE).unlink()
    gone = judge_ledger(run, load_run(run).messages)
    assert not gone.found and gone.never_ran == ["grasp (c1)", "observe (c2)"]  # the halted c3 was not done
    assert gone.summary().startswith(f"no ledger ({LEDGER_FILE}): answered done, never ran")


def test_torn_and_overlong_lines_are_skipped_and_counted(tmp_path: Path) -> None:
    run = _run(tmp_path)
    with (run / LEDGER_FILE).open("a") as f:
        f.write('{"event": "start", "conversation": "c9", ' + "x" * 2 * MAX_LINE_BYTES + "\n")
        f.write('{"event": "start", "conv')  # a killed ag_ex's last line
    read = read_ledger(run)
    assert read.found and len(read.entries) == 6 and read.skipped == 2
    summary = judge_ledger(run, load_run(run).messages).summary()
    assert summary.startswith("3 command(s) started by 1 ag_ex process(es), 2 unreadable line(s):")
    ledger = Ledger(run / LEDGER_FILE, life="300-cccccc")
    ledger.ended("c" * 5000, "grasp", 1.0, "failure: " + "y" * 5000)  # cut to fit a line
    ledger.close()
    last = read_ledger(run).entries[-1]
    assert len(last.conversation) == 256 and last.conversation.endswith("…")
    assert last.outcome is not None and len(last.outcome) == 256


def test_a_command_answered_from_the_ledger_after_a_restart_is_listed_not_twice(tmp_path: Path) -> None:
    """A restarted ag_ex answered c1 again from the ledger (a ``replayed`` line, no start): the
    question passes and chaos.md lists it. Planted: the restarted ag_ex started c1 again
    instead: executed twice."""
    run = _run(tmp_path)
    ledger = Ledger(run / LEDGER_FILE, life="200-bbbbbb")
    ledger.replayed("c1", "grasp", 2.0)
    ledger.close()
    v = verdict(run, _outcome())
    assert v.ok and v.ledger.replayed == ["grasp (c1)"] and v.ledger.runs == 3 and v.ledger.lives == 2
    text = write_chaos_report(run, chaos_scenario(0), _outcome(), v).read_text()
    assert "| nothing executed twice | yes " in text
    assert "(answered from the ledger after a restart: grasp (c1))" in text
    ran(run, ("c1", "grasp", 6.0, 7.0), life="200-bbbbbb")
    v = verdict(run, _outcome())
    assert not v.ok and v.ledger.twice == ["grasp (c1): started at 1.000, 6.000 s"]
