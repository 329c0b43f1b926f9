"""The scenario runner (services/scenario/runner.py) does not wait for a plan step that can no
longer come: once every command has its final report, a step triggered by a plan step that was
not seen ends the run with one clear reason instead of waiting for the scenario's time-out."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from services.fleet.launcher import LaunchError
from services.runtime.human import HumanReport, ReportKind
from services.scenario.model import Fault, Scenario, Step, Trigger
from services.scenario.runner import CommandRecord, ScenarioRunner
from shared.fipa_codec.languages.l_wm import WorldUpdate

KILL = Step(fault=Fault(service="ag_ex", kind="kill"), after=Trigger(step="tilt_pour/tilt", delay_s=1.0))


class _NoFleet:
    def dead(self) -> list[str]:
        return []


class _Hosting:
    fleet: Any = _NoFleet()


def _runner(tmp_path: Path, final: bool) -> ScenarioRunner:
    runner = ScenarioRunner(Scenario(name="t", steps=(KILL,)), tmp_path, hosting=_Hosting())  # type: ignore[arg-type]
    record = CommandRecord(1, "pour the jar into the bowl", "p-1")
    if final:
        record.final = HumanReport(request_id="p-1", kind=ReportKind.FAILED, text="no plan")
    runner.commands.append(record)
    return runner


def test_a_step_after_a_plan_step_that_cannot_come_ends_the_run(tmp_path: Path) -> None:
    runner = _runner(tmp_path, final=True)
    with pytest.raises(LaunchError, match="a step waits for 'tilt_pour/tilt', but every command has ended"):
        runner._play(None, KILL, time.monotonic() + 5)  # type: ignore[arg-type]


def test_a_step_waits_while_a_command_is_running(tmp_path: Path) -> None:
    runner = _runner(tmp_path, final=False)
    with pytest.raises(LaunchError, match="did not end within"):
        runner._play(None, KILL, time.monotonic() + 0.5)  # type: ignore[arg-type]


SAY_AFTER_RENEWAL = Step(say="pour the jar into the bowl", after=Trigger(renewed=True))


def test_a_step_after_the_renewal_waits_for_an_update_that_renews(tmp_path: Path) -> None:
    """``after = { renewed = true }`` is ready only once a_km was told an update that renews
    its picture (WorldUpdate.renews: a power-cycled robot's kitchen); other updates, which give
    a_km knowledge, do not make it ready, and a renewal that never comes ends the run at the
    scenario's deadline with the step it waited for."""
    runner = ScenarioRunner(Scenario(name="t", steps=(SAY_AFTER_RENEWAL,)), tmp_path, hosting=_Hosting())  # type: ignore[arg-type]
    runner._km_learnt(WorldUpdate(stamp=1.0, objects=()))
    assert runner.knowledge.is_set() and not runner._ready(SAY_AFTER_RENEWAL, 0)
    with pytest.raises(LaunchError, match="did not end within"):
        runner._play(None, SAY_AFTER_RENEWAL, time.monotonic() + 0.3)  # type: ignore[arg-type]
    runner._km_learnt(WorldUpdate(stamp=2.0, objects=(), renews=True))
    assert runner._ready(SAY_AFTER_RENEWAL, 0)
