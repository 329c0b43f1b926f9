"""What an operator expects of deploy/compose.yaml (docs/deploy.md, "Logs and health"), read as
``docker compose config`` reads it: every long-running service has a health check that starts
no Python and opens no connection to the router (a roco service's reads its ready file), every
service's log is rotated, the router's Zenoh log is at INFO and every roco process logs to
standard output. :func:`ops_problems` names what is missing; each check is also shown to fail
on the value the file had before (a planted fault)."""

from __future__ import annotations

import copy
import json
import re
import tomllib
from pathlib import Path
from typing import Any

import pytest

from services.deploy.compose import COMPOSE_FILE, READY_FILE, ComposeError, render
from services.spec.model import DEFAULT_SPEC, default_spec, load
from shared.settings import Settings

yaml = pytest.importorskip("yaml", reason="PyYAML reads the compose file: pip install -e '.[dev]'")

ONE_SHOT = {"certs"}
"""Services that run once and end: no health check."""
NOT_ROCO = {"viewer"}
"""Services that run no roco process (the Rerun viewer)."""
DEFAULT = re.compile(r"^\$\{[A-Z0-9_]+:-(?P<default>[^}]*)\}$")


def config(text: str) -> dict[str, Any]:
    loaded = yaml.safe_load(text)
    assert isinstance(loaded, dict)
    return loaded


def default_of(value: str) -> str:
    """``${VAR:-default}`` → ``default``; any other value is itself."""
    found = DEFAULT.match(value)
    return found.group("default") if found else value


def ops_problems(compose: dict[str, Any]) -> list[str]:
    """What the compose file ``compose`` (merge keys resolved) lacks of the module docstring's
    expectations, one line each; empty when it has them all."""
    problems = []
    ready, stdout = Settings.env_name("ready_file"), Settings.env_name("log_stdout")
    for name, service in compose["services"].items():
        logging = service.get("logging", {})
        options = logging.get("options", {})
        if logging.get("driver") != "json-file" or not options.get("max-size") or not options.get("max-file"):
            problems.append(f"{name}: no log rotation (json-file with max-size and max-file)")
        check = service.get("healthcheck", {})
        if name in ONE_SHOT:
            if check != {"disable": True}:
                problems.append(f"{name}: a one-shot service with a health check")
            continue
        test = check.get("test")
        if check.get("disable") or not test:
            problems.append(f"{name}: no health check")
            continue
        if any("python" in word for word in test):
            problems.append(f"{name}: its health check starts Python: {test}")
        if name in NOT_ROCO:
            continue
        env = service.get("environment", {})
        if test != ["CMD", "cat", READY_FILE] or env.get(ready) != READY_FILE:
            problems.append(f"{name}: its health check does not read its ready file ({ready}={READY_FILE})")
        if str(env.get(stdout)) != "1":
            problems.append(f"{name}: does not log to standard output ({stdout}=1)")
    router_log = default_of(str(compose["services"]["router"].get("environment", {}).get("RUST_LOG", "")))
    if router_log != "info":
        problems.append(f"router: Zenoh's log level is {router_log or 'unset'!r}, not 'info'")
    return problems


@pytest.fixture(scope="module")
def committed() -> dict[str, Any]:
    return config(COMPOSE_FILE.read_text())


def test_the_committed_file_has_health_checks_rotation_and_an_info_router(committed: dict[str, Any]) -> None:
    assert ops_problems(committed) == []
    assert committed["services"]["world"]["healthcheck"]["test"] == ["CMD", "cat", READY_FILE]
    assert default_of(committed["services"]["router"]["environment"]["RUST_LOG"]) == "info"


def test_the_checks_fail_on_the_old_values(committed: dict[str, Any]) -> None:
    """Planted faults: the values the file had before, put back one at a time."""
    old = copy.deepcopy(committed)
    old["services"]["world"]["healthcheck"] = {"disable": True}
    assert ops_problems(old) == ["world: no health check"]

    old = copy.deepcopy(committed)
    probe = ["CMD", "python", "-m", "services.runtime.health", "a_km"]
    old["services"]["a_km"]["healthcheck"]["test"] = probe
    assert ops_problems(old) == [
        f"a_km: its health check starts Python: {probe}",
        f"a_km: its health check does not read its ready file (ROCO_READY_FILE={READY_FILE})",
    ]

    old = copy.deepcopy(committed)
    for service in old["services"].values():
        service.pop("logging")
    assert ops_problems(old) == [
        f"{name}: no log rotation (json-file with max-size and max-file)" for name in old["services"]
    ]

    old = copy.deepcopy(committed)
    del old["services"]["router"]["environment"]["RUST_LOG"]  # the router's old default: DEBUG lines
    assert ops_problems(old) == ["router: Zenoh's log level is 'unset', not 'info'"]
    old["services"]["router"]["environment"]["RUST_LOG"] = "${ROCO_ROUTER_LOG:-debug}"
    assert ops_problems(old) == ["router: Zenoh's log level is 'debug', not 'info'"]

    old = copy.deepcopy(committed)
    for service in old["services"].values():
        service.get("environment", {}).pop("ROCO_LOG_STDOUT", None)
    roco = [n for n in old["services"] if n not in ONE_SHOT | NOT_ROCO]
    assert roco == ["router", "recorder", "world", *default_spec().launch_order]
    assert roco[3:9] == ["a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi"]  # the shipped agents first
    assert ops_problems(old) == [f"{n}: does not log to standard output (ROCO_LOG_STDOUT=1)" for n in roco]


def test_no_agent_asks_the_one_started_last(tmp_path: Path) -> None:
    """The last agent of ``start_order`` waits until every other is healthy, and an agent is
    healthy once it has seen the agents it asks: one that asked the last would wait forever."""
    path = tmp_path / "spec.toml"
    text = DEFAULT_SPEC.read_text()
    order = [n for n in tomllib.loads(text)["start_order"] if n != "a_ta"] + ["a_ta"]  # a_km asks a_ta
    line = f"start_order = {json.dumps(order)}"
    path.write_text(re.sub(r"(?ms)^start_order = \[.*?\]$", lambda _: line, text, count=1))
    with pytest.raises(
        ComposeError, match="agent a_km asks a_ta, which starts once every other agent is healthy"
    ):
        render(load(path))
    render(default_spec())  # the shipped order: nobody asks a_hi
