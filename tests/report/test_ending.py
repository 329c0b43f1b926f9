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
