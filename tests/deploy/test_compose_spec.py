"""deploy/compose.yaml against the specification (issue 17: the compose services are not a
second list of the agents): one service per agent of the specification, each running that
agent, and a_hi — the last in the specification's start order — started once every other agent
is healthy."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from services.spec.model import SpecError, default_spec, load

COMPOSE = Path(__file__).resolve().parents[2] / "deploy" / "compose.yaml"


def services(text: str) -> dict[str, str]:
    """Service name → its block of text (the file's ``services:`` section, two-space keys)."""
    body = text.split("\nservices:\n", 1)[1].split("\nvolumes:\n", 1)[0]
    parts = re.split(r"^  ([A-Za-z_][\w-]*):.*$", body, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def test_compose_runs_each_agent_of_the_specification_once() -> None:
    spec = default_spec()
    found = services(COMPOSE.read_text())
    agents = {name for name, block in found.items() if '"services.runtime.main"' in block}
    assert agents == set(spec.agent_names)
    for name in agents:
        assert f'"services.runtime.main", "{name}"]' in found[name], name


def test_the_last_agent_started_waits_for_every_other_one() -> None:
    spec = default_spec()
    last, others = spec.launch_order[-1], spec.launch_order[:-1]
    block = services(COMPOSE.read_text())[last]
    waited = set(re.findall(r"^      (\w+):\n        condition: service_healthy", block, flags=re.M))
    assert waited >= set(others)


def test_the_start_order_refuses_an_unknown_agent_and_starts_unnamed_ones_last(tmp_path: Path) -> None:
    text = (Path(__file__).resolve().parents[2] / "services/spec/robot_companion.toml").read_text()
    bad = tmp_path / "spec.toml"
    bad.write_text(text.replace('"ag_ex", "a_ta", "a_hi"]', '"ag_ex", "a_tx", "a_hi"]', 1))
    with pytest.raises(SpecError, match="start_order names unknown agent 'a_tx'"):
        load(bad)
    bad.write_text(text.replace('"ag_ex", "a_ta", "a_hi"]', '"ag_ex", "a_hi"]', 1))
    assert load(bad).launch_order == ("a_km", "a_pl", "a_co", "ag_ex", "a_hi", "a_ta")
