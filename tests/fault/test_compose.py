"""Compose faults as command lines (no Docker engine needed): process faults through
`docker compose`, partition through `docker network`, delay and loss through `tc netem`."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest

from services.fault.compose import Compose
from services.fault.process import FaultError

CID = "c0ffee123456"


class FakeDocker:
    """Answers the docker commands the fault layer runs; records them."""

    def __init__(
        self, networks: dict[str, dict[str, list[str] | None]] | None = None, plugin: bool = True
    ) -> None:
        self.calls: list[list[str]] = []
        self.networks: dict[str, dict[str, list[str] | None]] = (
            networks if networks is not None else {"deploy_default": {"Aliases": ["a_km", "c0ffee"]}}
        )
        self.plugin = plugin

    def __call__(self, args: Sequence[str]) -> subprocess.CompletedProcess[str]:
        args = list(args)
        self.calls.append(args)
        out, code, err = "", 0, ""
        if args[:3] == ["docker", "compose", "version"]:
            code = 0 if self.plugin else 1
        elif "ps" in args and "-q" in args:
            out = f"{CID}\n" if args[-1] != "viewer" else ""
        elif args[:2] == ["docker", "inspect"]:
            out = json.dumps(self.networks)
        elif args[-1] == "unknown":
            code, err = 1, "no such service: unknown"
        return subprocess.CompletedProcess(args, code, out, err)


@pytest.fixture
def docker(monkeypatch: pytest.MonkeyPatch) -> FakeDocker:
    monkeypatch.setattr("shutil.which", lambda name: f"/usr/bin/{name}")
    return FakeDocker()


def test_process_faults_are_docker_compose_commands(docker: FakeDocker, tmp_path: Path) -> None:
    dc = Compose(file=Path("deploy/compose.yaml"), project="roco", state_dir=tmp_path, run=docker)
    for action in ("kill", "stop", "start", "pause", "unpause", "restart"):
        ev = dc.process(action, "a_km")
        assert (ev.agent, ev.kind, ev.target) == ("roco", action, "a_km")
        assert docker.calls[-1] == [
            "docker",
            "compose",
            "-f",
            "deploy/compose.yaml",
            "-p",
            "roco",
            action,
            "a_km",
        ]
    with pytest.raises(FaultError, match="no service 'a_xx'"):
        dc.process("kill", "a_xx")


def test_docker_compose_v1_when_the_plugin_is_absent(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("shutil.which", lambda name: f"/usr/bin/{name}")
    fake = FakeDocker(plugin=False)
    Compose(file=Path("c.yaml"), state_dir=tmp_path, run=fake).process("pause", "a_co")
    assert fake.calls[-1] == ["docker-compose", "-f", "c.yaml", "pause", "a_co"]
    monkeypatch.setattr("shutil.which", lambda name: None)
    with pytest.raises(FaultError, match="neither 'docker compose' nor 'docker-compose'"):
        Compose(file=Path("c.yaml"), state_dir=tmp_path, run=fake).process("pause", "a_co")


def test_netem_delay_loss_and_clear(docker: FakeDocker, tmp_path: Path) -> None:
    dc = Compose(project="roco", state_dir=tmp_path, run=docker)
    ev = dc.netem("a_km", 0.2, 0.05)
    tc = ["tc", "qdisc", "replace", "dev", "eth0", "root", "netem", "delay", "200ms", "loss", "5%"]
    # as root in the container (the service runs as the image's user; NET_ADMIN is root's)
    assert docker.calls[-1] == ["docker", "exec", "-u", "0", CID, *tc]
    assert ev.detail == "netem delay 200ms loss 5%"
    dc.netem("a_km", 0.0, 0.0)
    assert docker.calls[-1] == ["docker", "exec", "-u", "0", CID, "tc", "qdisc", "del", "dev", "eth0", "root"]
    with pytest.raises(FaultError, match="viewer has no container"):
        dc.netem("viewer", 0.1, 0.0)


def test_partition_disconnects_every_network_and_heal_restores_aliases(
    docker: FakeDocker, tmp_path: Path
) -> None:
    docker.networks = {"roco_default": {"Aliases": ["a_km", "c0ffee"]}, "roco_sim": {"Aliases": None}}
    dc = Compose(project="roco", state_dir=tmp_path, run=docker)
    dc.partition("a_km")
    assert ["docker", "network", "disconnect", "roco_default", CID] in docker.calls
    assert ["docker", "network", "disconnect", "roco_sim", CID] in docker.calls
    assert dc.partitioned() == ["a_km"]
    dc.heal("a_km")
    assert ["docker", "network", "connect", "--alias", "a_km", "roco_default", CID] in docker.calls
    assert ["docker", "network", "connect", "--alias", "a_km", "roco_sim", CID] in docker.calls
    assert dc.partitioned() == []
    dc.heal("a_co")  # no record: the project's default network, the service name as alias
    assert docker.calls[-1] == ["docker", "network", "connect", "--alias", "a_co", "roco_default", CID]


def test_a_failing_docker_command_is_one_line(docker: FakeDocker, tmp_path: Path) -> None:
    dc = Compose(project="roco", state_dir=tmp_path, run=docker)
    with pytest.raises(FaultError) as info:
        dc._check(["docker", "compose", "kill", "unknown"], "docker compose kill unknown")
    assert str(info.value) == "docker compose kill unknown failed: no such service: unknown"
