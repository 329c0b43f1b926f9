"""The robot perceiving with its head camera (``ROCO_PERCEPTION=camera``), as a user
runs it: ``roco run "bring the cup to the table"``. Every pose the agents got is an estimate
from the rendered Kinect image, the report puts each beside the truth, and the task is judged
by the world it left."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from services.agents.knowledge.world_model import WorldModel
from services.report import build_report
from services.report.load import load_run
from services.report.world import final_world
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.machine import needs_gl

pytestmark = [pytest.mark.slow, pytest.mark.fleet, needs_gl]


@pytest.fixture(scope="module")
def camera_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str], Path]:
    runs = tmp_path_factory.mktemp("runs")
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "run", "bring the cup to the table", "--runs-dir", str(runs)],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "ROCO_PERCEPTION": "camera"},
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return proc, run_dir


def test_the_cup_is_brought_with_camera_perception_and_stands_at_its_place(camera_run: tuple) -> None:
    proc, run_dir = camera_run
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded"]
    world = final_world(run_dir)
    assert world is not None
    cup = next(o for o in world.objects if o.name == "cup")
    place = WorldModel().placement("cup", "table").positions[0]
    assert cup.pose.tilt() < math.radians(15) and math.dist(cup.pose.position, place) < 0.03, cup


def test_the_agents_got_estimates_and_the_report_sets_them_beside_the_truth(camera_run: tuple) -> None:
    _, run_dir = camera_run
    observations = [m.content for m in load_run(run_dir).messages if isinstance(m.content, Observation)]
    movable = [o for obs in observations for o in obs.objects if o.name in ("jar", "bowl", "cup")]
    assert movable and all(o.position_sigma is not None and o.position_sigma > 0 for o in movable)
    rows = build_report(run_dir).perception
    errors = sorted(r.error_mm for r in rows if r.error_mm is not None)
    assert errors and errors[int(0.95 * (len(errors) - 1))] <= 10.0, errors
    assert re.search(r"^## \d+\. Perception \(head camera\)$", (run_dir / "report.md").read_text(), re.M)
