"""A compose fleet as an operator meets it, without a Docker engine (the command runner
answers as docker would): the compose command chosen (v2 plugin or Debian's docker-compose
1.29), `roco fault net`'s error naming the missing piece (tc, NET_ADMIN, the kernel's netem)
and `roco fault` finding a running compose fleet without --compose."""

from __future__ import annotations

import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli.fault import fault_app
from services.deploy import engine
from services.deploy.engine import ComposeFleet, compose_command, run_name, running_fleets
from services.fault.compose import Compose
from services.fault.process import FaultError

CID = "c0ffee123456"
runner = CliRunner()


def _answers(table: dict[str, tuple[int, str, str]]) -> engine.Runner:
    """A runner answering the first entry whose key the command line starts with ("" matches
    anything); every call is kept in ``calls``."""

    def run(args: Sequence[str]) -> subprocess.CompletedProcess[str]:
        line = " ".join(args)
        run.calls.append(line)  # type: ignore[attr-defined]
        for start, (code, out, err) in table.items():
            if line.startswith(start):
                return subprocess.CompletedProcess(list(args), code, out, err)
        return subprocess.CompletedProcess(list(args), 1, "", "unknown")

    run.calls = []  # type: ignore[attr-defined]
    return run


def _on_path(*names: str) -> engine.Which:
    return lambda name: f"/usr/bin/{name}" if name in names else None


def test_compose_v2_where_the_plugin_answers_else_docker_compose_1_29_else_none() -> None:
    plugin = _answers({"docker compose version": (0, "Docker Compose version v2.27.0", "")})
    assert compose_command(plugin, _on_path("docker", "docker-compose")) == ["docker", "compose"]
    # Debian: docker.io has no plugin ("docker: unknown command: docker compose")
    debian = _answers({"docker compose version": (1, "", "docker: unknown command: docker compose")})
    assert compose_command(debian, _on_path("docker", "docker-compose")) == ["docker-compose"]
    assert compose_command(plugin, _on_path("docker-compose")) == ["docker-compose"]
    assert compose_command(debian, _on_path("docker")) is None


def test_the_tool_the_fault_layer_runs_is_the_one_chosen(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr("shutil.which", _on_path("docker", "docker-compose"))
    debian = _answers(
        {"docker compose version": (1, "", "unknown command"), "docker-compose": (0, f"{CID}\n", "")}
    )
    Compose(project="roco", state_dir=tmp_path, run=debian).process("kill", "a_km")
    assert debian.calls[-1] == "docker-compose -f deploy/compose.yaml -p roco kill a_km"  # type: ignore[attr-defined]


TC_OUTPUTS = {
    "tc": (
        126,
        "",
        'OCI runtime exec failed: exec failed: unable to start container process: exec: "tc": '
        "executable file not found in $PATH: unknown",
    ),
    "NET_ADMIN": (2, "", "RTNETLINK answers: Operation not permitted"),
    "kernel": (2, "", "Error: Specified qdisc kind is unknown."),
    "kernel, older iproute2": (2, "", "RTNETLINK answers: No such file or directory"),
}
"""What ``docker exec -u 0 CONTAINER tc qdisc replace … netem`` prints when each piece is missing."""
NAMED = {
    "tc": "image has no tc",
    "NET_ADMIN": "lacks the NET_ADMIN capability: start the fleet with -f deploy/compose.netfault.yaml",
    "kernel": "kernel has no netem (modprobe sch_netem",
    "kernel, older iproute2": "kernel has no netem (modprobe sch_netem",
}


@pytest.mark.parametrize("missing", list(TC_OUTPUTS))
def test_fault_net_names_the_missing_piece(
    missing: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr("shutil.which", _on_path("docker"))
    docker = _answers(
        {
            "docker compose version": (0, "v2", ""),
            "docker compose -f deploy/compose.yaml -p roco ps -q a_co": (0, f"{CID}\n", ""),
            f"docker exec -u 0 {CID} tc qdisc replace": TC_OUTPUTS[missing],
        }
    )
    dc = Compose(project="roco", state_dir=tmp_path, run=docker)
    with pytest.raises(FaultError) as info:
        dc.netem("a_co", 0.1, 0.01)
    message = str(info.value)
    assert NAMED[missing] in message, message
    others = [NAMED[m] for m in NAMED if NAMED[m] != NAMED[missing]]
    assert not any(o in message for o in others), message
    assert message.startswith("a_co") or missing.startswith("kernel")


def test_fault_finds_the_one_compose_fleet_running(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """No local fleet under --runs-dir, no --compose: the compose fleet that runs is the target
    (its project and compose file from its containers' labels); two running: exit 2 asking which."""
    compose_file = tmp_path / "compose.yaml"
    compose_file.write_text("services: {}\n")
    fleets = [ComposeFleet("roco", (compose_file,))]
    monkeypatch.setattr("services.fault.target.running_fleets", lambda: fleets)
    monkeypatch.delenv("ROCO_COMPOSE_PROJECT", raising=False)
    done: list[Compose] = []

    def process(self: Compose, action: str, service: str) -> object:
        done.append(self)
        raise FaultError("stop here")

    monkeypatch.setattr(Compose, "process", process)
    runs = tmp_path / "runs"
    result = runner.invoke(fault_app, ["pause", "a_km", "--runs-dir", str(runs)])
    assert result.exit_code == 1 and "stop here" in result.output
    assert (done[0].project, done[0].file) == ("roco", compose_file)
    fleets.append(ComposeFleet("other"))
    result = runner.invoke(fault_app, ["pause", "a_km", "--runs-dir", str(runs)])
    assert result.exit_code == 2 and "compose fleets roco, other run" in result.output
    assert "--compose --project NAME" in result.output
    fleets.clear()  # none runs: the local fleet's error says to add --compose
    result = runner.invoke(fault_app, ["pause", "a_km", "--runs-dir", str(runs)])
    assert result.exit_code == 1 and "a compose fleet: add --compose" in result.output
    assert len(done) == 1


def test_running_fleets_and_their_run_from_docker() -> None:
    ps = _answers(
        {"docker ps": (0, "roco\t/srv/roco/deploy/compose.yaml,/srv/roco/deploy/x.yaml\nci\t\n", "")}
    )
    assert running_fleets(ps, _on_path("docker")) == [
        ComposeFleet("ci"),
        ComposeFleet("roco", (Path("/srv/roco/deploy/compose.yaml"), Path("/srv/roco/deploy/x.yaml"))),
    ]
    assert running_fleets(ps, _on_path()) == []
    assert running_fleets(_answers({"docker ps": (1, "", "Cannot connect")}), _on_path("docker")) == []
    base = ["docker-compose", "-p", "roco"]
    volume = _answers({"docker-compose -p roco exec": (0, "20261127-061500\n", "")})
    assert run_name(base, volume) == "20261127-061500"
    logs = _answers(
        {
            "docker-compose -p roco exec": (1, "", "service router is not running"),
            "docker-compose -p roco logs": (0, "router_1 | roco-entrypoint: run 20261127-061500\n", ""),
        }
    )
    assert run_name(base, logs) == "20261127-061500"
    assert run_name(base, _answers({})) is None
