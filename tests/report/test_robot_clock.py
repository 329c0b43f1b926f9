"""The robot's clock of the report (services/report/robot_clock.py): ag_ex's answers mark
robot time against the recorder's wall clock; between marks it is interpolated, outside them
unknown, and a mark going back in robot time is left out."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from services.report.load import load_run
from services.report.robot_clock import RobotClock, robot_clock
from shared.fipa_codec.languages.l_ex import CommandResult, Wait
from shared.fipa_codec.languages.l_sd import Observation
from tests.report.conftest import RunBuilder


def test_robot_time_is_interpolated_between_the_marks_and_unknown_outside() -> None:
    clock = RobotClock(((2.0, 10.0), (4.0, 20.0), (5.0, 23.0)))
    assert clock.at(1.9) is None and clock.at(5.1) is None
    assert clock.at(2.0) == 10.0 and clock.at(5.0) == 23.0
    assert clock.at(3.0) == pytest.approx(15.0)  # the simulation ran 5× the wall clock here
    assert clock.at(4.5) == pytest.approx(21.5)
    assert clock.between(0.0, 4.9) == pytest.approx(10.0)  # first mark after 0, last before 4.9
    assert clock.between(4.1, 4.9) is None and clock.between(None, 5.0) is None
    assert RobotClock().at(3.0) is None


def test_the_marks_are_ag_exs_answers_on_c5_and_never_go_back(make_run: Callable[..., Path]) -> None:
    b = RunBuilder()
    b.add(1.0, "C5", "a_ta", "ag_ex", "request", Wait(duration=1.0), protocol="fipa-request")
    b.add(2.0, "C5", "ag_ex", "a_ta", "inform", CommandResult(command="wait", ok=True, sim_time=10.0))
    b.add(3.0, "C5", "ag_ex", "a_ta", "inform", CommandResult(command="wait", ok=True, sim_time=4.0))
    b.add(4.0, "C5", "ag_ex", "a_ta", "inform", Observation(stamp=12.0, objects=()))
    b.add(5.0, "C1", "a_ta", "a_co", "inform", CommandResult(command="wait", ok=True, sim_time=99.0))
    run = load_run(make_run(b, timing=False))
    # the answer at 3.0 s says 4.0 s of robot time, before 10.0 s: a world gone back, left out
    assert robot_clock(run.messages).marks == ((2.0, 10.0), (4.0, 12.0))
