"""The scenario runner (services/scenario/runner.py) starts again an agent, the traffic recorder
or the router that exited though nobody stopped it (a receiving thread that ended:
services/runtime/main.py ``EXIT_LOST``; a router killed from outside), up to ``MAX_CRASHES``
times, and keeps its exit codes; the world process exiting ends the run. What the agents raised
is in the outcome's summary and makes it not clean."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from services.fleet.launcher import LaunchError
from services.runtime.human import HumanReport, ReportKind
from services.runtime.run_folder import read_run_info
from services.scenario.model import Scenario, Step
from services.scenario.runner import MAX_CRASHES, CommandRecord, ScenarioOutcome, ScenarioRunner
from tests.support.fake_hosting import FakeFleet, FakeHosting, FakeProcess


def _runner(tmp_path: Path) -> tuple[ScenarioRunner, FakeFleet]:
    fleet = FakeFleet(
        {
            "a_ta": FakeProcess(100),
            "recorder": FakeProcess(200),
            "router": FakeProcess(300),
            "world": FakeProcess(400),
        }
    )
    runner = ScenarioRunner(
        Scenario(name="t", steps=(Step(say="pour"),)), tmp_path, hosting=FakeHosting(fleet)
    )  # type: ignore[arg-type]
    runner.session = object()  # type: ignore[assignment]  # the fleet has started
    return runner, fleet


def test_an_agent_that_exited_by_itself_is_started_again_and_kept(tmp_path: Path) -> None:
    runner, fleet = _runner(tmp_path)
    said: list[str] = []
    runner.echo = said.append
    fleet.processes["a_ta"].returncode = 70
    runner._pump(0.0, math.inf)
    assert fleet.restarted == ["a_ta"] and runner.crashed == {"a_ta": [70]}
    assert said and said[-1].endswith("a_ta exited (code 70, see logs/a_ta.log); started again (pid 101)")
    assert read_run_info(tmp_path).processes["a_ta"] == 101
    runner._pump(0.0, math.inf)  # alive again: nothing more
    assert fleet.restarted == ["a_ta"]


def test_an_agent_that_keeps_exiting_ends_the_run(tmp_path: Path) -> None:
    runner, fleet = _runner(tmp_path)
    for _ in range(MAX_CRASHES):
        fleet.processes["a_ta"].returncode = 1
        runner._pump(0.0, math.inf)
    fleet.processes["a_ta"].returncode = 1
    with pytest.raises(LaunchError, match="process a_ta exited during the run"):
        runner._pump(0.0, math.inf)
    assert runner.crashed == {"a_ta": [1] * MAX_CRASHES}


@pytest.mark.parametrize(
    ("name", "log"), [("recorder", "logs/recorder.log"), ("router", "logs/router.stderr")]
)
def test_the_recorder_and_the_router_are_started_again_too(tmp_path: Path, name: str, log: str) -> None:
    runner, fleet = _runner(tmp_path)
    said: list[str] = []
    runner.echo = said.append
    fleet.processes[name].returncode = -9
    runner._pump(0.0, math.inf)
    assert fleet.restarted == [name] and runner.crashed == {name: [-9]}
    pid = fleet.processes[name].pid
    assert said[-1].endswith(f"{name} exited (code -9, see {log}); started again (pid {pid})")
    outcome = ScenarioOutcome([], crashed=runner.crashed)
    assert outcome.raised_line().endswith(f"{name} exited (code -9) and was started again: see {log}")


def test_the_world_process_exiting_ends_the_run(tmp_path: Path) -> None:
    runner, fleet = _runner(tmp_path)
    fleet.processes["world"].returncode = 1
    with pytest.raises(LaunchError, match="process world exited during the run"):
        runner._pump(0.0, math.inf)
    assert fleet.restarted == []


def test_what_the_agents_raised_is_in_the_summary_and_the_outcome_is_not_clean() -> None:
    record = CommandRecord(1, "pour the jar into the bowl", "r1")
    record.final = HumanReport(request_id="r1", kind=ReportKind.SUCCEEDED, text="done")
    clean = ScenarioOutcome([record])
    assert clean.ok and clean.clean and clean.raised_line() == "" and "raised" not in clean.summary()
    dirty = ScenarioOutcome([record], raised={"a_ta": {"handler_errors": 2}}, crashed={"a_km": [70]})
    assert dirty.ok and not dirty.clean
    assert dirty.summary().splitlines()[-1] == (
        "agents raised: 2 handler errors in a_ta: see logs/a_ta.log; "
        "a_km exited (code 70) and was started again: see logs/a_km.log"
    )
