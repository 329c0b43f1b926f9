"""The library's scenarios with everything real: ``roco scenario NAME`` starts a router, the
recorder and one process per agent, ag_ex simulates Velma in MuJoCo, and the scenario's
expectations are checked; the run folder's report is read back (services/scenario/library)."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from services.report import build_report
from services.report.load import load_run
from services.runtime.run_folder import read_run_info
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.machine import needs_camera
from tests.support.world import FULL, START, stands_at, untouched, world

pytestmark = [pytest.mark.slow, pytest.mark.fleet]

Run = tuple[subprocess.CompletedProcess[str], Path]
"""A scenario's ``roco scenario`` process (output, exit status) and its run folder."""


def scenario(name: str, runs: Path) -> Run:
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "scenario", name, "--runs-dir", str(runs), "--quiet"],
        capture_output=True,
        text=True,
        timeout=1500,
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    # self-collision is on: in no scenario does a command make the robot touch itself
    touched = [e.text for e in build_report(run_dir).events if e.kind == "self_contact"]
    assert touched == [], touched
    return proc, run_dir


def sw_states(run_dir: Path) -> list[SWStatus]:
    return [
        m.content
        for m in load_run(run_dir).messages
        if m.channel == "C1" and m.sender == "a_ta" and isinstance(m.content, SWStatus)
    ]


@pytest.fixture(scope="module")
def urgent_mid_pour(tmp_path_factory: pytest.TempPathFactory) -> Run:
    return scenario("urgent_mid_pour", tmp_path_factory.mktemp("runs"))


@pytest.fixture(scope="module")
def two_commands(tmp_path_factory: pytest.TempPathFactory) -> Run:
    return scenario("two_commands", tmp_path_factory.mktemp("runs"))


def test_an_urgent_command_preempts_the_pour_which_resumes(urgent_mid_pour: Run) -> None:
    proc, run_dir = urgent_mid_pour
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["succeeded", "succeeded"]
    texts = [e.text for e in report.coordination]
    cancel = next(i for i, t in enumerate(texts) if t.startswith("cancel"))
    terminating = next(i for i, t in enumerate(texts) if t.startswith("Terminating"))
    preempted = next(i for i, t in enumerate(texts) if t.startswith("Preempted"))
    assert cancel < terminating < preempted
    assert "put the jar down on the table" in texts[preempted]
    # the cup's plan ran between the preemption and the pour's end, and the pour finished
    assert re.search(r"^## \d+\. Commands and coordination", (run_dir / "report.md").read_text(), re.M)
    w = world(run_dir)
    assert stands_at(w["cup"], "table") and stands_at(w["bowl"], "table"), w
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]
    from services.spec_check.conformance import verify_report

    conforms, text = verify_report(run_dir)
    assert conforms, text  # cancel, Terminating, Preempted all within the coordinate protocol


def test_two_commands_in_a_row(two_commands: Run) -> None:
    proc, run_dir = two_commands
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["succeeded", "succeeded"]
    w = world(run_dir)
    assert stands_at(w["cup"], "table") and stands_at(w["bowl"], "table"), w
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


@needs_camera
@pytest.mark.parametrize("run", ["urgent_mid_pour", "two_commands"])
def test_the_head_camera_counts_most_spheres_in_the_bowl_after_the_pour(
    run: str, request: pytest.FixtureRequest
) -> None:
    """The content share of the last Observation of the bowl (services/report/content.py), the
    head camera's count: the pour, resumed after the preemption or followed by another
    command, left most spheres in the bowl."""
    _, run_dir = request.getfixturevalue(run)
    content = build_report(run_dir).content
    assert content.observed and content.share is not None and content.share >= 0.9, content


def test_an_object_moved_after_it_was_seen_makes_a_ta_replan(tmp_path: Path) -> None:
    proc, run_dir = scenario("moved_object", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    reasons = [s.reason or "" for s in sw_states(run_dir) if s.state is SWState.REPLAN]
    assert any("jar is 4 cm from where the plan expects it" in r for r in reasons), reasons
    w = world(run_dir)
    assert stands_at(w["bowl"], "table") and (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


def test_impossible_commands_are_refused_with_a_reason(tmp_path: Path) -> None:
    proc, run_dir = scenario("impossible", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    # the teapot never becomes a command: a_hi names the word it does not know (the scenario
    # checks its answer), so only the pour into the cabinet reaches the report's commands
    assert [c.outcome for c in build_report(run_dir).commands] == ["failed"]
    w = world(run_dir)
    assert all(untouched(w[n]) for n in START), w  # nothing was moved


def test_a_km_restarted_between_commands_keeps_its_knowledge(tmp_path: Path) -> None:
    proc, run_dir = scenario("km_restart", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    log = (run_dir / "logs" / "a_km.log").read_text()
    assert "knowledge kept" in log
    info = read_run_info(run_dir)
    assert info.commands == ["bring the cup to the table", "bring the cup to the table"]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded", "failed"]
    w = world(run_dir)
    assert stands_at(w["cup"], "table") and untouched(w["jar"]) and untouched(w["bowl"]), w


def test_a_stop_mid_pour_puts_both_down_and_the_pour_asked_again_succeeds(tmp_path: Path) -> None:
    proc, run_dir = scenario("stop_mid_pour", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["stopped", "succeeded"]
    # the bowl first: the jar's turn and carry then pass clear of it (planner/clearance.py)
    put = "put the bowl down on the table and the jar down on the table"
    assert any(put in e.text for e in report.coordination), [e.text for e in report.coordination]
    # the second pour found the jar standing where the stop put it: no look missed it
    assert not any("was not seen" in e.text for e in report.coordination)
    w = world(run_dir)
    assert stands_at(w["bowl"], "table") and (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


def test_after_the_pour_jar_and_bowl_go_back_in_the_cabinet(tmp_path: Path) -> None:
    proc, run_dir = scenario("tidy_up", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded"] * 3
    w = world(run_dir)
    assert stands_at(w["jar"], "cabinet") and stands_at(w["bowl"], "cabinet"), w
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


def test_a_pour_interrupted_twice_in_its_tilt_still_fills_the_bowl(tmp_path: Path) -> None:
    """a_ta, then ag_ex, killed half-way through the tilt (scenario tilt_interrupted): each
    time a_ta reports Replan, the pour is replanned and finishes; the world shows the bowl on
    the table with the content in it."""
    proc, run_dir = scenario("tilt_interrupted", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded"]
    assert sum(s.state is SWState.REPLAN for s in sw_states(run_dir)) >= 2
    w = world(run_dir)
    assert stands_at(w["bowl"], "table") and (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]
    assert w["jar"].pose.position[2] > 0.5  # still in the hand or on furniture, not dropped


def test_a_placed_bowl_knocked_over_fails_the_task_with_the_reason(tmp_path: Path) -> None:
    proc, run_dir = scenario("knocked_bowl", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["failed"]
    errors = [s.reason or "" for s in sw_states(run_dir) if s.state is SWState.ERROR]
    assert any("localise_bowl" in r and "the bowl is not upright: it leans 180°" in r for r in errors), errors
    bowl = world(run_dir)["bowl"]
    assert bowl.pose.tilt() > math.radians(170)  # still upside down where the person left it
