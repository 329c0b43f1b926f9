"""deploy/compose.yaml from the specification (services/deploy/compose.py, ``roco deploy
compose``): the committed file is the rendered one; read as ``docker compose config`` reads it
(YAML merge keys resolved), each of the six agents' services is what the fleet needs (its
command, environment, volumes, start order, capabilities, health check); a new agent of the
specification gets a service and a_hi — the last agent ``start_order`` names — waits for it."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import msgspec
import pytest
from typer.testing import CliRunner

from services.cli.deploy import deploy_app
from services.deploy.compose import (
    AGENT_EXTRAS,
    COMPOSE_FILE,
    IMAGES,
    MOUNTS,
    READY_FILE,
    ComposeError,
    agent_extras,
    check,
    difference,
    last_started,
    render,
)
from services.deploy.layout import layout_for
from services.spec.model import DEFAULT_SPEC, AgentSpec, SpecError, default_spec, load
from tests.spec_check.walkthrough import walkthrough_spec

yaml = pytest.importorskip("yaml", reason="PyYAML reads the compose file: pip install -e '.[dev]'")

ROOT = Path(__file__).resolve().parents[2]
SPEC = default_spec()
AGENTS = ("a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi")
runner = CliRunner()


def config(text: str) -> dict[str, Any]:
    """The compose file as docker compose reads it: YAML 1.1 with its merge keys resolved."""
    loaded = yaml.safe_load(text)
    assert isinstance(loaded, dict)
    return loaded


def test_the_committed_compose_file_is_what_the_specification_gives() -> None:
    problem = check(COMPOSE_FILE, SPEC, "deploy/compose.yaml")
    assert problem is None, problem
    assert COMPOSE_FILE == ROOT / "deploy" / "compose.yaml"


def test_the_six_agents_services_are_what_the_fleet_needs() -> None:
    """The meaning of each agent's service, key by key (what `docker compose config` shows)."""
    compose = config(COMPOSE_FILE.read_text())
    assert "version" not in compose  # the Compose Specification format
    assert set(compose) == {
        "x-roco",
        "x-roco-robot",
        "x-roco-viewer",
        "x-env",
        "x-after-router",
        "services",
        "volumes",
    }
    services = compose["services"]
    assert list(services) == ["certs", "router", "recorder", "world", *SPEC.launch_order, "viewer"]
    assert SPEC.launch_order[: len(AGENTS)] == AGENTS  # each of these, key by key; one added since below
    assert compose["volumes"] == {"fleet": {}, "km_store": {}, "co_state": {}}
    env = compose["x-env"]
    assert env["ROCO_ROUTER"] == "${ROCO_PROTO:-tls}/router:7447" and env["ROCO_RUN_DIR"] == "/runs/{run}"
    after_router = {
        "certs": {"condition": "service_completed_successfully"},
        "router": {"condition": "service_healthy"},
        "recorder": {"condition": "service_healthy"},
    }
    mounts = ["${ROCO_RUNS:-../runs}:/runs", "fleet:/var/lib/roco/fleet"]
    for name in AGENTS:
        service = services[name]
        image = IMAGES[agent_extras(SPEC, name).image]
        assert service["image"] == f"${{{image.variable}:-{image.default}}}"
        assert service["build"] == {
            "context": "..",
            "dockerfile": "deploy/Dockerfile",
            "target": image.target,
            "args": {
                "BASE": "${ROCO_BASE:-python:3.11-slim}",
                "BUILD_BASE": "${ROCO_BUILD_BASE:-python:3.11-slim}",
            },
        }
        assert service["user"] == "${ROCO_UID:-10001}:${ROCO_GID:-10001}"  # the image's roco, not root
        assert service["init"] is True and service["restart"] == "unless-stopped"
        assert service["command"] == ["python", "-m", "services.runtime.main", name]
        assert service["healthcheck"] == {
            "interval": "5s",
            "timeout": "5s",
            "retries": 5,
            "start_period": "120s",
            "test": ["CMD", "cat", READY_FILE],
        }
        extra_env = {
            "a_km": {"ROCO_KM_STORE": "/var/lib/roco/km/{run}"},
            "a_co": {"ROCO_STATE_DIR": "/var/lib/roco/co/{run}"},
        }.get(name, {})
        assert service["environment"] == {**env, **extra_env}
        extra_volume = {"a_km": ["km_store:/var/lib/roco/km"], "a_co": ["co_state:/var/lib/roco/co"]}
        own = [f"${{ROCO_CERTS:-./certs}}/{e}:/certs/{e}:ro" for e in ("ca.pem", name)]  # and no other's
        assert service["volumes"] == mounts + own + extra_volume.get(name, [])
        assert service.get("cap_add") is None  # not root: a capability would not count
        assert {service["mem_limit"], service["cpus"], service["pids_limit"]} != {None}
        last = SPEC.launch_order[-1]  # a_hi in the shipped specification; an agent added since
        others = (o for o in SPEC.launch_order if o != last)
        waits = {o: {"condition": "service_healthy"} for o in others} if name == last else {}
        if name == "ag_ex":  # the robot it drives: the world, whose shared memory and processes it sees
            waits = {"world": {"condition": "service_healthy"}}
            assert service["ipc"] == service["pid"] == "service:world"
        assert service["depends_on"] == {**after_router, **waits}
        assert set(service) <= {
            "image", "build", "init", "restart", "logging", "volumes", "healthcheck",
            "command", "environment", "depends_on", "ipc", "pid", "user",
            "mem_limit", "cpus", "pids_limit",
        }  # fmt: skip
    world = services["world"]  # Velma's hardware: no Zenoh, not an agent
    assert world["command"] == ["python", "-m", "velma.world"] and world["environment"] == env
    assert world["ipc"] == "shareable" and world["depends_on"] == {"router": {"condition": "service_healthy"}}


def test_the_other_services_keep_their_settings() -> None:
    services = config(COMPOSE_FILE.read_text())["services"]
    assert services["certs"]["restart"] == "no" and services["certs"]["healthcheck"] == {"disable": True}
    assert services["router"]["ports"] == ["${ROCO_ROUTER_PUBLISH:-127.0.0.1:7447}:7447"]
    assert services["router"]["environment"]["ROCO_NEW_RUN"] == "1"
    assert services["router"]["healthcheck"]["test"] == ["CMD", "cat", READY_FILE]
    assert services["recorder"]["stop_grace_period"] == "60s"
    assert services["viewer"]["volumes"] == ["${ROCO_RUNS:-../runs}:/runs:ro"]
    viewer_health = services["viewer"]["healthcheck"]["test"]
    assert viewer_health[:3] == ["CMD", "bash", "-c"]
    assert "/dev/tcp/127.0.0.1/9876" in viewer_health[3] and "/dev/tcp/127.0.0.1/9090" in viewer_health[3]
    assert config(COMPOSE_FILE.read_text())["x-roco"]["volumes"] == list(MOUNTS)
    # the viewer image (with the Rerun CLI) for the viewer and the recorder (`rerun rrd merge`)
    for name in ("recorder", "viewer"):
        assert services[name]["image"] == "${ROCO_VIEWER_IMAGE:-roco-viewer:latest}"
        assert services[name]["build"]["target"] == "viewer"
    for name in ("certs", "router", "world"):
        assert services[name]["image"] == "${ROCO_IMAGE:-roco:latest}"
        assert services[name]["build"]["target"] == "runtime"


@pytest.mark.walkthrough
def test_a_new_agent_gets_a_service_and_waits_for_the_others(tmp_path: Path) -> None:
    spec = load(walkthrough_spec(tmp_path / "spec.toml"))  # docs/spec.md's new agent a_wt
    order = spec.launch_order
    assert order[order.index("a_hi") + 1] == "a_wt"  # it asks a_hi: right after it
    assert last_started(spec) == order[-1]  # a_wt in the shipped specification
    services = config(render(spec))["services"]
    assert list(services) == ["certs", "router", "recorder", "world", *order, "viewer"]
    new, plain = services["a_wt"], services["a_pl"]
    assert new["command"] == ["python", "-m", "services.runtime.main", "a_wt"]
    for key in set(plain) - {"command", "volumes", "depends_on"}:
        assert new[key] == plain[key], key
    assert new["volumes"] == [v.replace("a_pl", "a_wt") for v in plain["volumes"]]
    # the agent started last (the watcher, unless the specification has grown since) waits for
    # every other agent to be healthy, a_hi among them
    waiting = services[order[-1]]["depends_on"]
    assert {a for a, c in waiting.items() if c == {"condition": "service_healthy"}} >= set(order[:-1])
    # the committed file lacks it, and says how to bring it up to date
    assert difference(COMPOSE_FILE.read_text(), spec) == "no service for agent a_wt"
    assert check(COMPOSE_FILE, spec, "deploy/compose.yaml") == (
        "deploy/compose.yaml differs from what the specification gives (no service for agent a_wt): "
        "run `roco deploy compose`"
    )


@pytest.mark.walkthrough
def test_roco_deploy_compose_writes_and_checks_the_file(tmp_path: Path) -> None:
    spec_file = walkthrough_spec(tmp_path / "spec.toml")
    target = tmp_path / "compose.yaml"
    target.write_text(COMPOSE_FILE.read_text())
    args = ["--file", str(target), "--spec", str(spec_file)]
    r = runner.invoke(deploy_app, ["compose", "--check", *args])
    assert r.exit_code == 1
    assert r.output.strip().endswith(
        "differs from what the specification gives (no service for agent a_wt): run "
        f"`roco deploy compose --spec {spec_file} --file {target}`"
    )
    assert r.output.count("\n") == 1 and r.output.startswith("roco: ")
    r = runner.invoke(deploy_app, ["compose", *args])
    assert r.exit_code == 0 and r.output.startswith("roco: wrote "), r.output
    # a specification outside roco's tree is another system: its folder mounted, ROCO_SPEC there
    assert target.read_text() == render(load(spec_file), layout_for(spec_file, target))
    assert "    - .:/system:ro\n" in target.read_text()
    r = runner.invoke(deploy_app, ["compose", "--check", *args])
    assert r.exit_code == 0 and r.output.strip().endswith("is what the specification gives"), r.output
    r = runner.invoke(deploy_app, ["compose", *args])
    assert r.exit_code == 0 and "is up to date" in r.output
    r = runner.invoke(deploy_app, ["compose", "--check", "--file", str(tmp_path / "none.yaml")])
    assert r.exit_code == 2 and r.output == f"roco: {tmp_path / 'none.yaml'}: no such compose file\n"


def test_an_agent_that_cannot_be_a_service_is_refused() -> None:
    for bad in ("viewer", "a km"):
        agents = (*SPEC.agents, AgentSpec(name=bad, group="x", implementation="m:C"))
        with pytest.raises(ComposeError, match=f"agent {bad!r} cannot be a compose service"):
            render(msgspec.structs.replace(SPEC, agents=agents))


def test_each_agents_extras_are_for_an_agent_and_its_run_variables_are_the_entrypoints() -> None:
    assert set(AGENT_EXTRAS) <= set(SPEC.agent_names)
    entrypoint = (ROOT / "deploy" / "entrypoint.sh").read_text()
    substituted = re.search(r"for var in ([A-Z_ ]+); do", entrypoint)
    assert substituted, "deploy/entrypoint.sh no longer says which variables it gives the run's name"
    for extras in AGENT_EXTRAS.values():
        if extras.state is not None:
            assert set(extras.state.variables) <= set(substituted.group(1).split())


def test_the_start_order_refuses_an_unknown_agent_and_starts_unnamed_ones_last(tmp_path: Path) -> None:
    text = DEFAULT_SPEC.read_text()
    order = list(SPEC.start_order)

    def with_order(names: list[str]) -> str:  # the start_order line as the data gives it
        line = f"start_order = {json.dumps(names)}"
        return re.sub(r"(?ms)^start_order = \[.*?\]$", lambda _: line, text, count=1)

    bad = tmp_path / "spec.toml"
    bad.write_text(with_order([n if n != "a_ta" else "a_tx" for n in order]))
    with pytest.raises(SpecError, match="start_order names unknown agent 'a_tx'"):
        load(bad)
    bad.write_text(with_order([n for n in order if n != "a_ta"]))
    unnamed = (a for a in SPEC.agent_names if a == "a_ta" or a not in SPEC.start_order)
    assert load(bad).launch_order == (*(n for n in order if n != "a_ta"), *unnamed)
