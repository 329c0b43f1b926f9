"""The exact interface check: an agent whose roles, handlers or code differ from its
interface in the specification refuses to start with one line naming what is wrong, and
``roco spec verify-code`` names the same without starting it. The faults are planted in
tests/spec_check/planted/ (one a_pl per module)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

from services.runtime.memory_transport import MemoryBus
from services.runtime.roles import RoleMismatch
from services.spec.model import DEFAULT_SPEC
from services.spec_check.code_check import verify_code_report

PLANTED = {
    "variable_send": "agent a_pl uses Performative.PROPOSE, which none of its roles may send "
    "(variable_send.py:",
    "raw_send": "agent a_pl sends with self.engine.send to a_hi outside its roles (raw_send.py:",
    "no_channel": "agent a_pl opens fipa-query on C2, where it declares no initiator role (no_channel.py:",
    "named_channel": "agent a_pl opens fipa-query on C7, where it declares no initiator role "
    "(named_channel.py:",
    "wrong_role": "agent a_pl declares itself initiator of fipa-request on C3, but [[channels]] C3 makes it "
    "the participant",
    "role_removed": "agent a_pl declares no initiator role for fipa-query on C4, which [[channels]] C4 "
    "gives it",
    "wrong_language": "agent a_pl: its fipa-request role on C3 speaks L_WM, but [[channels]] C3 carries "
    "L_HFSM",
    "dead_comparison": "agent a_pl has no handler for request received as participant of fipa-request on C3",
}


@pytest.mark.parametrize(("module", "line"), PLANTED.items(), ids=list(PLANTED))
def test_a_planted_fault_refuses_the_start_with_one_line(module: str, line: str) -> None:
    planner = importlib.import_module(f"tests.spec_check.planted.{module}").Planner
    with pytest.raises(RoleMismatch) as refused:
        planner(MemoryBus().transport())
    text = str(refused.value)
    assert text.startswith(line) and "\n" not in text, text


def test_a_dead_comparison_is_named_besides_the_missing_handler() -> None:
    from services.runtime.roles import agent_problems
    from services.spec.model import default_spec
    from tests.spec_check.planted.dead_comparison import Planner

    problems = agent_problems(default_spec(), "a_pl", Planner)
    assert any(
        "compares a performative (the roles route what arrives) (dead_comparison.py:" in p for p in problems
    )


def test_verify_code_names_every_planted_fault_without_starting_an_agent(tmp_path: Path) -> None:
    shipped = DEFAULT_SPEC.read_text()
    old = 'implementation = "services.agents.planner.agent:Planner"'
    assert shipped.count(old) == 1
    path = tmp_path / "spec.toml"
    # the package is the folder: verify-code reads every planted module
    path.write_text(shipped.replace(old, 'implementation = "tests.spec_check.planted.variable_send:Planner"'))
    ok, text = verify_code_report(path)
    assert not ok
    for module in ("variable_send", "raw_send", "no_channel", "named_channel", "dead_comparison"):
        line = PLANTED[module] if module != "dead_comparison" else "compares a performative"
        assert line in text, (module, text)
    assert re.search(r"^a_pl: \d+ files; 2 protocol roles:$", text, re.M), text
