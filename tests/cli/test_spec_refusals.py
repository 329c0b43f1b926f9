"""Every ``roco spec`` command (and ``roco deploy compose``) refuses a specification file it
cannot read in one line starting with ``roco:``, exit 2, whatever the command does with it; and
``roco spec verify-code`` lists an agent whose code it cannot find as a problem of its report,
with the other agents' lines."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

import services.cli as cli
from services.spec.model import DEFAULT_SPEC

RUN = Path(__file__).parents[1] / "spec_check" / "two_hosts_run"
COMMANDS = [
    ["spec", "show"],
    ["spec", "check"],
    ["spec", "deadlock"],
    ["spec", "verify-code"],
    ["spec", "names", "--check"],
    ["spec", "verify", str(RUN)],
    ["spec", "what-if", str(RUN)],
    ["spec", "trace", str(RUN)],
    ["deploy", "compose", "--check"],
]
UNREADABLE = {
    "not TOML": ("not toml [[", "Expected '=' after a key"),
    "no agents": ('system = "RoCo"\n[[steps]]\nnumber = 1\n', "Object missing required field"),
    "missing": (None, "no such specification file"),
}


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: " ".join(c[:2]))
@pytest.mark.parametrize("case", sorted(UNREADABLE))
def test_a_specification_that_does_not_load_is_one_roco_line_and_exit_2(
    command: list[str], case: str, tmp_path: Path
) -> None:
    text, says = UNREADABLE[case]
    path = tmp_path / "spec.toml"
    if text is not None:
        path.write_text(text)
    result = CliRunner().invoke(cli.app, [*command, "--spec", str(path)], prog_name="roco")
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert lines[0].startswith(f"roco: {path}") and says in lines[0], lines[0]


def test_verify_code_lists_an_agent_whose_code_is_missing_among_the_others(tmp_path: Path) -> None:
    path = tmp_path / "spec.toml"
    shipped = DEFAULT_SPEC.read_text()
    path.write_text(
        shipped.replace("services.agents.planner.agent:Planner", "services.nowhere.agent:Planner")
    )
    result = CliRunner().invoke(cli.app, ["spec", "verify-code", "--spec", str(path)], prog_name="roco")
    assert result.exit_code == 1, result.output
    assert (
        "- agent a_pl: implementation 'services.nowhere.agent:Planner': no module 'services.nowhere.agent'"
        in result.output
    )
    assert "a_pl: its code is not read" in result.output
    assert "a_km: 6 files;" in result.output and result.output.rstrip().endswith("1 problem(s)")
