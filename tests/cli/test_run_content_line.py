"""`roco run`'s last line says whose count of the spheres in the bowl it gives: the robot's
(a_ta's last look) and, when the simulated world left its final scene, the simulation's beside
it (services/report/content.py ``content_line``; services/spec_check/run_report.py). A run
folder with a planted record and final scene, no fleet."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from services.cli.report import finish_report
from services.report.content import content_line
from services.report.model import ContentOutcome
from services.runtime.run_folder import RunInfo, write_run_info
from services.spec_check.run_report import content_clause
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from tests.report.conftest import RunBuilder, write_traffic
from tests.support.final_scene import BOWL_PLACE, plant_final_scene

COUNTED = ContentOutcome(container="bowl", observed=True, inside=18, total=18)


def test_the_line_gives_the_robot_s_count_as_the_robot_s() -> None:
    assert content_line(COUNTED) == "18 of 18 spheres in the bowl by the robot's count"
    assert (
        content_line(ContentOutcome(container="bowl", observed=False)) == "content not observed by the robot"
    )


def test_the_line_gives_the_simulation_s_count_beside_the_robot_s() -> None:
    assert (
        content_line(COUNTED, (16, 18))
        == "18 of 18 spheres in the bowl by the robot's count (the simulation's: 16)"
    )
    assert content_line(ContentOutcome(container="bowl", observed=False), (17, 18)) == (
        "content not observed by the robot (the simulation's: 17 of 18 in the bowl)"
    )


def _pour_run(run_dir: Path, robot_count: int) -> RunInfo:
    """A run folder of a pour whose record ends with ag_ex's Observation counting
    ``robot_count`` of 18 spheres in the bowl."""
    b = RunBuilder()
    saw = Observation(
        stamp=50.0,
        objects=(ObjectObservation(name="bowl", pose=Pose(BOWL_PLACE), particles_inside=robot_count),),
        total_particles=18,
    )
    b.add(3.0, "C5", "ag_ex", "a_ta", "inform", saw, protocol="fipa-request", conversation="c1")
    write_traffic(run_dir, b)
    now = time.time()
    info = RunInfo(started=now - 12.0, ended=now, succeeded=True, commands=["pour the jar into the bowl"])
    write_run_info(run_dir, info)
    return info


@pytest.mark.parametrize(
    ("in_bowl", "commands", "said"),
    [
        (
            17,
            ["pour the jar into the bowl"],
            "18 of 18 spheres in the bowl by the robot's count (the simulation's: 17)",
        ),
        (None, ["pour the jar into the bowl"], "18 of 18 spheres in the bowl by the robot's count"),
        (17, ["bring me the cup"], "1 command(s)"),
    ],
    ids=["simulated world", "no final scene", "no pour"],
)
def test_the_line_s_outcome_takes_the_simulation_s_count_from_the_world_s_final_scene(
    tmp_path: Path, in_bowl: int | None, commands: list[str], said: str
) -> None:
    """The robot counted 18; the world process left 17 in the bowl (or no final scene, as
    with ROCO_WORLD=loop)."""
    from services.report import build_report

    info = _pour_run(tmp_path, 18)
    info.commands = commands
    if in_bowl is not None:
        plant_final_scene(tmp_path, in_bowl)
    assert content_clause(tmp_path, info, build_report(tmp_path).content) == said


def test_roco_run_s_last_line_says_whose_count_it_gives(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    info = _pour_run(tmp_path, 18)
    plant_final_scene(tmp_path, 18)
    finish_report(tmp_path, info)
    line = capsys.readouterr().out.splitlines()[-1]
    assert line.startswith("roco: succeeded in 12.0 s wall; 1 communicates; "), line
    said = "18 of 18 spheres in the bowl by the robot's count (the simulation's: 18)"
    assert line.endswith(f"; {said}; report {tmp_path / 'report.md'}"), line
