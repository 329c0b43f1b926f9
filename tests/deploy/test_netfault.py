"""deploy/compose.netfault.yaml (services/deploy/netfault.py): the override that grants
NET_ADMIN for `roco fault net` is the rendered one, names every service a network fault
reaches, and `roco deploy compose --check` catches it out of date; where docker-compose is
installed, the merge grants NET_ADMIN beside every service's own keys (its limits)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli.deploy import deploy_app
from services.deploy import netfault
from services.deploy.compose import COMPOSE_FILE
from services.fault.compose import COMPOSE_SERVICES, NETFAULT_FILE
from services.spec.model import default_spec
from velma.world.mode import WORLD_SERVICE

yaml = pytest.importorskip("yaml", reason="PyYAML reads the compose file: pip install -e '.[dev]'")

ROOT = Path(__file__).resolve().parents[2]
SPEC = default_spec()


def test_the_committed_override_is_the_rendered_one_and_grants_net_admin_to_every_faulted_service() -> None:
    path = netfault.beside(COMPOSE_FILE)
    assert path == ROOT / NETFAULT_FILE
    assert netfault.check(path, SPEC) is None
    services = yaml.safe_load(path.read_text())["services"]
    # every service a fault reaches but the world, whose link to ag_ex is shared memory
    assert set(services) == set(COMPOSE_SERVICES) - {WORLD_SERVICE}
    assert all(s == {"cap_add": ["NET_ADMIN"]} for s in services.values())


def test_check_names_a_service_left_without_net_admin(tmp_path: Path) -> None:
    (tmp_path / "compose.yaml").write_text(COMPOSE_FILE.read_text())
    override = tmp_path / netfault.NAME
    override.write_text(netfault.render(SPEC).replace("  a_co:\n    cap_add: [NET_ADMIN]\n", ""))
    result = CliRunner().invoke(deploy_app, ["compose", "--check", "--file", str(tmp_path / "compose.yaml")])
    assert result.exit_code == 1
    assert "no NET_ADMIN for a_co" in result.output and "roco deploy compose" in result.output
    result = CliRunner().invoke(deploy_app, ["compose", "--file", str(tmp_path / "compose.yaml")])
    assert result.exit_code == 0 and f"wrote {override}" in result.output
    assert override.read_text() == netfault.render(SPEC)


@pytest.mark.skipif(shutil.which("docker-compose") is None, reason="needs docker-compose (Debian's 1.29)")
def test_docker_compose_merges_the_override_keeping_each_services_keys() -> None:
    merged = subprocess.run(
        ["docker-compose", "-f", str(COMPOSE_FILE), "-f", str(ROOT / NETFAULT_FILE), "-p", "roco", "config"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout
    services = yaml.safe_load(merged)["services"]
    caps = {name: set(s.get("cap_add", ())) for name, s in services.items()}
    assert caps["ag_ex"] == {"NET_ADMIN"}
    assert all(s["mem_limit"] and s["cpus"] and s["pids_limit"] for s in services.values())
    assert all("NET_ADMIN" in caps[s] for s in COMPOSE_SERVICES if s != WORLD_SERVICE)
    assert not caps["world"] and not caps["certs"]
