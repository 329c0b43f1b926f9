"""The end of a fleet of ``roco up`` / ``roco hosts up`` (services/report/ending.py): run.json
gets the commands the fleet was given and their outcomes from its own C2 traffic (not from
``roco send``), and the report is written — whether it was given none, several, or was
interrupted."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from services.report.ending import commands_summary, end
from services.runtime.run_folder import RunCommand, RunInfo, read_run_info, write_run_info
from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, TaskAtom
from tests.report.conftest import COMMAND_TEXT, STARTED, RunBuilder

BRING = "bring the cup"
FILL = "fill the bowl"


def _fleet(make_run: Callable[..., Path], builder: RunBuilder) -> Path:
    """A run folder as ``roco up`` leaves it: run.json without commands, the traffic."""
    run = make_run(builder, info=False)
    write_run_info(run, RunInfo(started=STARTED, router="tcp/127.0.0.1:7447", processes={"a_hi": 1}))
    return run


def _more_commands(b: RunBuilder) -> RunBuilder:
    """After the pour: a second command the person stopped, a third not ended."""
    second: dict[str, Any] = dict(conversation="cmd-2", protocol="fipa-request")
    b.add(
        45.0,
        "C2",
        "a_hi",
        "a_co",
        "request",
        HumanCommand(text=BRING, goal=TaskAtom("bring", ("cup",))),
        **second,
    )
    b.add(45.1, "C2", "a_co", "a_hi", "agree", **second)
    b.add(46.0, "C2", "a_hi", "a_co", "cancel", **second)
    outcome = CommandOutcome(command_id="cmd-2", succeeded=False, detail="stopped as asked")
    b.add(47.0, "C2", "a_co", "a_hi", "inform", outcome, **second)
    third: dict[str, Any] = dict(conversation="cmd-3", protocol="fipa-request")
    b.add(
        48.0,
        "C2",
        "a_hi",
        "a_co",
        "request",
        HumanCommand(text=FILL, goal=TaskAtom("fill", ("bowl",))),
        **third,
    )
    return b


def test_the_commands_and_outcomes_come_from_the_fleet_s_own_traffic(
    make_run: Callable[..., Path], pour: RunBuilder
) -> None:
    run = _fleet(make_run, _more_commands(pour))
    ending = end(run, ended=STARTED + 50.0)
    info = read_run_info(run)
    assert info == ending.info
    assert info.commands == [COMMAND_TEXT, BRING, FILL]
    assert (info.command, info.command_sent) == (COMMAND_TEXT, STARTED + 10.0)
    assert [(c.text, c.outcome, c.sent, c.ended) for c in info.outcomes] == [
        (COMMAND_TEXT, "succeeded", STARTED + 10.0, STARTED + 44.0),
        (BRING, "stopped", STARTED + 45.0, STARTED + 47.0),
        (FILL, None, STARTED + 48.0, None),
    ]
    assert info.ended == STARTED + 50.0
    assert info.succeeded is False  # the third had not ended
    assert info.detail == (
        "#1 succeeded: poured 17 of 20; #2 stopped: stopped as asked; "
        f"#3 not ended when the fleet stopped: {FILL}"
    )
    assert info.processes == {"a_hi": 1} and info.router == "tcp/127.0.0.1:7447"  # kept
    assert ending.path == run / "report.md" and ending.path.is_file()
    assert ending.communicates == len(pour.records)
    assert ending.line() == (
        f"after 50.0 s; 3 commands: 1 succeeded, 1 stopped, 1 not ended; {len(pour.records)} communicates; "
        f"report {run / 'report.md'}"
    )
    assert BRING in ending.path.read_text()  # the report's command table


def test_done_or_stopped_at_the_person_s_request_is_a_success(
    make_run: Callable[..., Path], pour: RunBuilder
) -> None:
    run = _fleet(make_run, pour)
    assert end(run, ended=STARTED + 50.0).info.succeeded is True


def test_a_fleet_given_no_command_ends_with_no_outcome(make_run: Callable[..., Path]) -> None:
    run = _fleet(make_run, RunBuilder())
    ending = end(run, ended=STARTED + 5.0)
    info = read_run_info(run)
    assert (info.commands, info.outcomes, info.succeeded) == ([], [], None)
    assert info.detail == "no command was given" and info.ended == STARTED + 5.0
    assert ending.line().startswith("after 5.0 s; no command given; 0 communicates; report ")
    assert (run / "report.md").is_file()


def test_a_fleet_that_ended_early_says_why_first(make_run: Callable[..., Path], pour: RunBuilder) -> None:
    run = _fleet(make_run, pour)
    info = end(run, ended=STARTED + 50.0, failure="interrupted").info
    assert info.succeeded is False
    assert info.detail == "interrupted; #1 succeeded: poured 17 of 20"


def test_a_folder_that_cannot_be_read_is_said_not_raised(tmp_path: Path) -> None:
    ending = end(tmp_path / "gone", ended=1.0)
    assert ending.path is None and "run folder not found" in ending.problem
    assert ending.line() == "(its start unknown); no command given; report not written: " + ending.problem


def test_the_summary_counts_each_outcome() -> None:
    assert commands_summary([]) == "no command given"
    one = RunCommand(text="a", outcome="failed")
    assert commands_summary([one]) == "1 command: 1 failed"


def _second_command(b: RunBuilder, start: float = 60.0) -> RunBuilder:
    """After the pour (10 → 44 s, 20 s of robot time): "bring the cup", asked at ``start`` s
    and done 5 s later, ag_ex answering 1.5 s of robot time apart in between."""
    conv: dict[str, Any] = dict(conversation="cmd-2", protocol="fipa-request")
    b.add(
        start,
        "C2",
        "a_hi",
        "a_co",
        "request",
        HumanCommand(text=BRING, goal=TaskAtom("bring", ("cup",))),
        **conv,
    )
    b.add(start + 0.1, "C2", "a_co", "a_hi", "agree", **conv)
    for k, robot in enumerate((100.0, 101.5)):
        b.add(
            start + 1.0 + k,
            "C5",
            "ag_ex",
            "a_ta",
            "inform",
            CommandResult(command="move", ok=True, sim_time=robot),
            conversation=f"ex-bring-{k}",
            protocol="fipa-request",
        )
    outcome = CommandOutcome(command_id="cmd-2", succeeded=True, detail="the cup is on the table")
    b.add(start + 5.0, "C2", "a_co", "a_hi", "inform", outcome, **conv)
    return b


def test_the_report_gives_each_command_its_own_duration(
    make_run: Callable[..., Path], pour: RunBuilder
) -> None:
    """Two commands (the pour, 34 s; then "bring the cup", 5 s, 16 s later): the report times
    each apart, in wall-clock and robot time, and names the span from the first to the last as
    no task's duration (it holds the 16 s the fleet waited)."""
    run = _fleet(make_run, _second_command(pour))
    ending = end(run, ended=STARTED + 70.0)
    assert ending.path is not None
    md = ending.path.read_text()
    assert (
        "| Task durations | 2 commands, each from its request to its outcome: "
        "#1 34.0 s wall, 20.0 s robot time (at 10.0 s); #2 5.0 s wall, 1.5 s robot time (at 60.0 s); "
        "first command → last outcome: 55.0 s wall |"
    ) in md
    assert "| task duration (wall clock) | #1 34.0 s, #2 5.0 s | the same (a real robot) |" in md
    assert "| task duration (robot time) | #1 20.0 s robot time, #2 1.5 s robot time |" in md
    assert f"| 2 | {BRING} | 0 | 60.0 |  | 65.0 | 5.0 | succeeded |" in md
    assert "55.0 s wall (human command" not in md  # no single duration summing both
