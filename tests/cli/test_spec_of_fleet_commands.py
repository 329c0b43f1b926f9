"""The commands that start a fleet or work on one read its specification: ``roco run --spec``
runs another system, ``roco scenario`` and ``roco chaos`` refuse one in one line (their
scenarios and verdict are the kitchen's), ``roco hosts up --spec`` checks it before making
anything, and ``roco gateway`` and ``roco sniff`` on a fleet of the sorting cell
(tests/support/cell_fleet.py) use the cell's without a flag."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

import services.cli as cli
from services.fleet.launcher import free_port
from services.hosts.fleet import placement
from services.spec.model import default_spec, load
from shared.settings import Settings
from tests.support.cell_fleet import CELL, CELL_AGENTS, cell_fleet
from tests.support.codec_registry import languages_leave_with_each_test  # noqa: F401  (autouse)

ROOT = Path(__file__).resolve().parents[2]


def invoke(args: list[str]) -> tuple[int, list[str]]:
    result = CliRunner().invoke(cli.app, args, prog_name="roco")
    return result.exit_code, result.output.strip().splitlines()


@pytest.fixture
def runner_given(monkeypatch: pytest.MonkeyPatch) -> dict[str, object]:
    """What ``roco run`` hands the scenario runner (its keyword arguments), the runner stopping
    at once (interrupted: exit 130, nothing started)."""
    given: dict[str, object] = {}

    class Runner:
        def __init__(self, sc: object, run_dir: Path, **kwargs: object) -> None:
            given.update(kwargs)

        def run(self) -> object:
            raise KeyboardInterrupt

    monkeypatch.setattr("services.scenario.runner.ScenarioRunner", Runner)
    monkeypatch.setattr("signal.signal", lambda *args: None)  # pytest keeps its SIGTERM
    return given


def test_roco_run_starts_the_fleet_of_its_spec(runner_given: dict[str, object], tmp_path: Path) -> None:
    code, _ = invoke(["run", "sort 3 bolts", "--spec", str(CELL), "--live", "--runs-dir", str(tmp_path)])
    assert code == 130
    env = runner_given["env"]
    assert isinstance(env, dict) and env[Settings.env_name("spec")] == str(CELL.resolve())
    watch = getattr(runner_given["on_session"], "__self__", None)
    assert watch is not None and watch.state.expected == CELL_AGENTS
    runner_given.clear()
    code, _ = invoke(["run", "pour", "--runs-dir", str(tmp_path)])  # the kitchen: as it was
    env = runner_given["env"]
    assert code == 130 and isinstance(env, dict) and Settings.env_name("spec") not in env


def test_roco_run_needs_an_agent_that_plays_the_person(
    runner_given: dict[str, object], tmp_path: Path
) -> None:
    load(CELL)  # the cell's package importable beside the copy of its specification
    spec = tmp_path / "cell.toml"
    text = CELL.read_text()
    assert text.count('role = "person"\n') == 1
    spec.write_text(text.replace('role = "person"\n', ""))
    code, lines = invoke(["run", "sort 3 bolts", "--spec", str(spec), "--runs-dir", str(tmp_path / "runs")])
    assert (code, lines) == (2, ['roco: no agent of SortingCell plays the person\'s role (role = "person")'])
    assert not (tmp_path / "runs").exists() and not runner_given


@pytest.mark.parametrize(
    ("args", "why"),
    [
        (["scenario", "urgent_mid_pour"], "roco scenario plays the kitchen's scenarios"),
        (["chaos"], "roco chaos judges the kitchen's task"),
    ],
    ids=["scenario", "chaos"],
)
def test_kitchen_commands_refuse_another_system_in_one_line(
    args: list[str], why: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def started(*args: object, **kwargs: object) -> None:
        raise AssertionError("something was started")

    monkeypatch.setattr("services.scenario.runner.ScenarioRunner.__init__", started)
    runs = tmp_path / "runs"
    code, lines = invoke([*args, "--spec", str(CELL), "--runs-dir", str(runs)])
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"roco: {why}") and f"SortingCell ({CELL}) has no a_km, " in lines[0]
    assert lines[0].endswith("; run it with roco run --spec, or roco up --spec and roco send")
    assert not runs.exists()


def test_roco_hosts_up_checks_its_spec_before_making_anything(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def started(*args: object, **kwargs: object) -> None:
        raise AssertionError("the two hosts were started")

    monkeypatch.setattr("services.hosts.fleet.TwoHosts.start", started)
    monkeypatch.setattr("services.hosts.netns.unavailable", lambda link=True: None)  # root, ip, nft
    monkeypatch.setattr("signal.signal", lambda *args: None)
    missing, runs = tmp_path / "none.toml", tmp_path / "runs"
    code, lines = invoke(["hosts", "up", "--spec", str(missing), "--runs-dir", str(runs)])
    assert code == 1 and lines == [f"roco: {missing}: no such specification file"]
    assert not runs.exists()


def test_the_two_hosts_place_the_agents_of_the_specification() -> None:
    assert placement(CELL_AGENTS) == {"brain": ["recorder", *CELL_AGENTS], "robot": []}
    # the robot's host keeps C5's two ends; every other agent, a grown one included, is the brain's
    order = default_spec().launch_order
    assert placement(order) == {
        "brain": ["recorder", *(a for a in order if a not in ("ag_ex", "a_ta"))],
        "robot": ["ag_ex", "a_ta"],
    }
    assert {"a_km", "a_pl", "a_co", "a_hi"} <= set(placement(order)["brain"])


def test_roco_gateway_serves_the_fleet_s_specification(tmp_path: Path) -> None:
    """The cell has no external role: the gateway of its fleet says so (the kitchen's has one,
    and would try its router)."""
    cell_fleet(tmp_path / "runs")
    done = subprocess.run(
        [sys.executable, "-m", "services.cli", "gateway", "--port", str(free_port())],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr == f"roco: gateway: {CELL}: no external role ([[externals]]): nobody may come in\n"


def test_roco_sniff_filters_by_the_fleet_s_agents_and_channels(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """a_so and C2 are the cell's: the filters pass, and the sniffer stops at the fleet's router,
    which is gone."""
    monkeypatch.setattr("signal.signal", lambda *args: None)
    runs = tmp_path / "runs"
    cell_fleet(runs)
    code, lines = invoke(["sniff", "--agent", "a_so", "--channel", "C2", "--runs-dir", str(runs)])
    assert code == 1 and len(lines) == 1 and lines[0].startswith("roco: no router answers at "), lines
    code, lines = invoke(["sniff", "--agent", "a_km", "--runs-dir", str(runs)])
    assert code == 2 and lines == ["roco: unknown agent 'a_km' (known: a_op, a_so, a_cv)"], lines
