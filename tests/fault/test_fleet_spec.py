"""``roco fault`` knows the services, agents and channels of the fleet it acts on from that
fleet's specification (services/fault/): the one its run folder keeps, else ``--spec``, else
the shipped one. A fleet of the sorting cell (tests/support/cell_fleet.py, no process of it
runs) has the cell's, not the kitchen's; the kitchen's own are as before."""

from __future__ import annotations

import dataclasses
import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.cli.fault import _fleet
from services.fault import process
from services.fault.compose import COMPOSE_SERVICES, Compose, compose_services, joined_services
from services.fault.process import FaultError, UpFleet, local_services
from services.fleet.launcher import AGENT_ORDER
from services.spec.model import DEFAULT_SPEC, default_spec, load
from tests.support.cell_fleet import CELL, CELL_AGENTS, cell_fleet
from tests.support.codec_registry import languages_leave_with_each_test  # noqa: F401  (autouse)
from velma.world.mode import WORLD_SERVICE


def _fault(*args: str) -> tuple[int, list[str]]:
    """``roco fault ARGS…``: its exit status and the lines it wrote on stderr."""
    done = CliRunner().invoke(app, ["fault", *args])
    return done.exit_code, done.stderr.strip().splitlines()


def test_the_services_are_those_of_the_specification() -> None:
    cell = load(CELL)
    assert local_services(cell) == ("router", "recorder", *CELL_AGENTS)  # no robot: no world
    assert compose_services(cell) == ("router", *CELL_AGENTS, "recorder", "viewer")
    kitchen = default_spec()
    assert local_services(kitchen) == ("router", "recorder", WORLD_SERVICE, *AGENT_ORDER)
    assert compose_services(kitchen) == COMPOSE_SERVICES
    assert ("router", WORLD_SERVICE, *AGENT_ORDER, "recorder", "viewer") == COMPOSE_SERVICES
    # ag_ex shares the world's namespaces: a fault that starts the world starts it after
    assert joined_services(kitchen) == {WORLD_SERVICE: ("ag_ex",)} and joined_services(cell) == {}


def test_a_fleet_of_roco_up_runs_the_specification_its_run_folder_keeps(tmp_path: Path) -> None:
    cell_fleet(tmp_path)
    fleet = UpFleet.load(tmp_path)
    assert fleet.agents == CELL_AGENTS
    assert UpFleet.load(tmp_path, DEFAULT_SPEC).agents == AGENT_ORDER  # --spec over it
    with pytest.raises(FaultError, match="no service 'a_km' in a local fleet"):
        process.kill(fleet, "a_km")


def test_on_a_cell_fleet_the_kitchen_s_agents_are_no_services(tmp_path: Path) -> None:
    cell_fleet(tmp_path)
    runs = ["--runs-dir", str(tmp_path)]
    assert _fault("kill", "a_km", *runs) == (
        2,
        ["roco: no service 'a_km' in a local fleet (services: router, recorder, a_cv, a_so, a_op)"],
    )
    assert _fault("kill", "a_so", *runs) == (1, ["roco: a_so is not running"])  # a service of it
    code, lines = _fault("net", "a_km", "--loss", "0.1", *runs)
    assert code == 2 and lines == [
        "roco: network faults of 'a_km' need --compose "
        "(locally only the agents a_cv, a_so, a_op have the fault layer)"
    ]
    assert _fault("msg", "C4", "--drop", "0.1", *runs) == (
        2,
        ["roco: unknown channel 'C4' (channels: C1, C2, or '*')"],
    )
    assert _fault("clear", "C4", *runs) == (2, ["roco: 'C4' is neither a channel (C1, C2) nor a service"])


def test_spec_names_the_system_where_no_fleet_keeps_one(tmp_path: Path) -> None:
    """Without a fleet, --spec (or ROCO_SPEC) says whose services are meant; the kitchen's
    otherwise."""
    runs = ["--runs-dir", str(tmp_path)]
    assert _fault("kill", "a_so", *runs, "--spec", str(CELL)) == (
        1,
        [f"roco: no fleet is up (no {tmp_path / '.fleet.json'}); start one with 'roco up' "
         "(a compose fleet: add --compose)"],
    )  # fmt: skip
    code, lines = _fault("kill", "a_so", *runs)
    assert code == 2 and lines[0].startswith("roco: no service 'a_so' in a local fleet (services: router")


def test_a_compose_fleet_s_services_follow_spec(tmp_path: Path) -> None:
    dc, system = _fleet(True, "cell", None, tmp_path, None, CELL)
    assert system.system == "SortingCell"
    assert isinstance(dc, Compose) and dc.services == compose_services(system) and dc.project == "cell"
    with pytest.raises(FaultError, match=r"no service 'a_km' \(services: router, a_cv, a_so, a_op, recorder"):
        dc.process("kill", "a_km")
    dc, system = _fleet(True, "roco", None, tmp_path, None, None)
    assert dc is not None and dc.services == COMPOSE_SERVICES and system == default_spec()


def _recorded(dc: Compose, action: str, service: str) -> list[list[str]]:
    """The docker commands ``dc.process(action, service)`` runs, after finding compose."""
    calls: list[list[str]] = []

    def run(args: Sequence[str]) -> subprocess.CompletedProcess[str]:
        calls.append(list(args))
        return subprocess.CompletedProcess(args, 0, "", "")

    dataclasses.replace(dc, run=run).process(action, service)
    return [c for c in calls if c[-1] != "version"]


def test_a_restart_of_the_world_starts_ag_ex_again_once_the_world_is_back() -> None:
    """Docker's restart manager gives up on a container that joins the namespaces of one that
    is not running yet; the fault starts ag_ex itself, after the world."""
    dc = Compose(project="p")
    restart = _recorded(dc, "restart", WORLD_SERVICE)
    # started as it is (compose up would make it anew in the fault command's environment)
    assert [c[-2:] for c in restart] == [["restart", WORLD_SERVICE], ["start", "ag_ex"]]
    assert [c[-2:] for c in _recorded(dc, "start", WORLD_SERVICE)][-1] == ["start", "ag_ex"]
    assert [c[-2:] for c in _recorded(dc, "stop", WORLD_SERVICE)] == [["stop", WORLD_SERVICE]]
    assert [c[-2:] for c in _recorded(dc, "restart", "a_km")] == [["restart", "a_km"]]
    # planted: without the joined services, ag_ex would be left exited
    alone = dataclasses.replace(dc, joined={})
    assert [c[-2:] for c in _recorded(alone, "restart", WORLD_SERVICE)] == [["restart", WORLD_SERVICE]]
