"""`roco down --compose` without a Docker engine (docker's answers given): it finds the running
compose fleet, its run's name and run folder on the host, stops it with the compose command
there is (docker-compose 1.29 here) and writes the run's report and run.json with each
command's outcome, as `roco down` does for a local fleet."""

from __future__ import annotations

import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.runtime.run_folder import RunInfo, read_run_info, write_run_info
from tests.report.conftest import COMMAND_TEXT, STARTED, pour_run, write_traffic

RUN = "20261127-061500"
CID = "c0ffee123456"


class Docker:
    """Answers as an engine with compose project ``roco`` running; records every command."""

    def __init__(self, runs: Path, compose_file: Path) -> None:
        self.runs, self.file, self.calls = runs, compose_file, list[str]()

    def __call__(self, args: Sequence[str]) -> subprocess.CompletedProcess[str]:
        line = " ".join(args)
        self.calls.append(line)
        base = f"docker-compose -f {self.file} -p roco"
        answers = {
            "docker compose version": (1, "", "docker: unknown command: docker compose"),
            "docker ps": (0, f"roco\t{self.file}\n", ""),
            f"{base} exec -T router cat": (0, f"{RUN}\n", ""),
            f"{base} ps -q router": (0, f"{CID}\n", ""),
            "docker inspect": (0, f"{self.runs}\n", ""),
            f"{base} down": (0, "", "Removing roco_router_1 ... done"),
        }
        code, out, err = next((a for k, a in answers.items() if line.startswith(k)), (1, "", "unknown"))
        return subprocess.CompletedProcess(list(args), code, out, err)


@pytest.fixture
def docker(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Docker:
    compose_file = tmp_path / "deploy" / "compose.yaml"
    compose_file.parent.mkdir()
    compose_file.write_text("services: {}\n")
    fake = Docker(tmp_path / "runs", compose_file)
    run_dir = fake.runs / RUN
    (run_dir / "logs").mkdir(parents=True)
    write_run_info(run_dir, RunInfo(started=STARTED, router="tls/router:7447"))  # as the entrypoint does
    write_traffic(run_dir, pour_run())
    monkeypatch.setattr("services.deploy.engine.run_command", fake)
    monkeypatch.setattr("shutil.which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setattr(
        "services.control.stop.save_compose_counters", lambda *a: " (counters not asked here)"
    )
    monkeypatch.delenv("ROCO_COMPOSE_PROJECT", raising=False)
    return fake


def test_roco_down_compose_stops_the_fleet_and_writes_its_report(docker: Docker) -> None:
    result = CliRunner().invoke(app, ["down", "--compose"])
    assert result.exit_code == 0, result.output
    run_dir = docker.runs / RUN
    assert f"docker-compose -f {docker.file} -p roco down" in docker.calls
    lines = result.output.splitlines()
    assert lines[0] == "roco: compose project roco stopped (counters not asked here)"
    assert lines[1].startswith(f"roco: run {run_dir} after ")
    assert lines[1].endswith(f"1 command: 1 succeeded; 40 communicates; report {run_dir / 'report.md'}")
    assert "| Command | pour the jar into the bowl |" in (run_dir / "report.md").read_text()
    info = read_run_info(run_dir)
    assert [(c.text, c.outcome) for c in info.outcomes] == [(COMMAND_TEXT, "succeeded")]
    assert info.succeeded is True and info.ended is not None


def test_a_run_folder_not_on_this_host_is_said_to_have_no_report(docker: Docker) -> None:
    (docker.runs / RUN / "run.json").unlink()
    docker.runs = docker.runs / "elsewhere"  # the mount names a folder without the run
    result = CliRunner().invoke(
        app, ["down", "--compose", "--project", "roco", "--compose-file", str(docker.file)]
    )
    assert result.exit_code == 1
    assert "report not written" in result.output.splitlines()[-1]


def test_no_compose_fleet_running_is_one_line(docker: Docker, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("services.deploy.engine.running_fleets", lambda run: [])
    result = CliRunner().invoke(app, ["down", "--compose"])
    assert (result.exit_code, result.output) == (
        2,
        "roco: no compose fleet runs: say which with --project NAME\n",
    )
