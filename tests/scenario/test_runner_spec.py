"""The scenario runner (services/scenario/runner.py, behind ``roco run``) follows the
specification its fleet runs (``ROCO_SPEC`` of its environment): the sorting cell's agents are
the ones started again when they exit, its operator is the one the person talks to, and it
starts without the kitchen's initial knowledge of a_km."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from services.runtime.human import HumanReport, ReportKind
from services.scenario.model import Scenario, Step
from services.scenario.runner import CommandRecord, ScenarioRunner, system_of
from services.spec.model import default_spec
from shared.settings import Settings
from tests.support.cell_fleet import CELL, CELL_AGENTS
from tests.support.codec_registry import languages_leave_with_each_test  # noqa: F401  (autouse)
from tests.support.fake_hosting import FakeFleet, FakeHosting, FakeProcess

CELL_ENV = {Settings.env_name("spec"): str(CELL)}


def _cell_runner(tmp_path: Path, fleet: FakeFleet, echo: list[str] | None = None) -> ScenarioRunner:
    scenario = Scenario(name="", steps=(Step(say="sort 3 bolts"),))
    hosting: Any = FakeHosting(fleet)
    return ScenarioRunner(
        scenario, tmp_path, env=CELL_ENV, hosting=hosting, echo=None if echo is None else echo.append
    )


def test_the_specification_of_the_fleet_s_environment() -> None:
    assert system_of(CELL_ENV).launch_order == CELL_AGENTS
    assert system_of({}) is default_spec()


def test_a_cell_agent_that_exited_by_itself_is_started_again(tmp_path: Path) -> None:
    fleet = FakeFleet({"a_so": FakeProcess(100, returncode=1)})
    runner = _cell_runner(tmp_path, fleet)
    runner._pump(0.0, math.inf)
    assert fleet.restarted == ["a_so"] and runner.crashed == {"a_so": [1]}


def test_the_person_talks_to_the_cell_s_operator(tmp_path: Path) -> None:
    said: list[str] = []
    runner = _cell_runner(tmp_path, FakeFleet(), said)
    assert runner.person == "a_op"
    runner.commands.append(CommandRecord(1, "sort 3 bolts", "r1"))
    runner._take("report", HumanReport(request_id="r1", kind=ReportKind.SUCCEEDED, text="sorted"))
    assert said[-1].endswith("a_op → person (#1): succeeded: sorted")


def test_the_cell_starts_without_the_kitchen_s_initial_knowledge(tmp_path: Path) -> None:
    runner = _cell_runner(tmp_path, FakeFleet())
    t0 = time.monotonic()
    runner._await_knowledge(math.inf)
    assert time.monotonic() - t0 < 1.0 and not runner.knowledge.is_set()
