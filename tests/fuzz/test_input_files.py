"""Malformed input files given to the CLI and the specification loader: one clear
line naming the file and the place (line and column, or the key path), and a non-zero exit."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.fleet_state import FLEET_FILE
from services.scenario.model import ScenarioError, load_scenario
from services.spec.model import DEFAULT_SPEC, SpecError, load

SPEC = DEFAULT_SPEC.read_text()
SPEC_CASES = {
    "syntax": (
        SPEC.replace("[protocols.fipa-query]", "[protocols.fipa-query", 1),
        r"at line \d+, column \d+",
    ),
    "type": (
        SPEC.replace('initiator = "a_co"', "initiator = 3", 1),
        r"\$\.channels\[\d+\]\.protocols\[\d+\]\.initiator",
    ),
    "unknown_field": (SPEC.replace('system = "', 'bogus = 1\nsystem = "', 1), r"unknown field `bogus`"),
    "unknown_agent": (
        re.sub(
            r'(\[\[channels\]\]\s*\n\s*name = "C1"\s*\n\s*ends = \[)"(\w+)"', r'\1"nobody"', SPEC, count=1
        ),
        r"channel C1 names unknown agent 'nobody'",
    ),
}


@pytest.mark.parametrize("case", sorted(SPEC_CASES))
def test_a_malformed_specification_is_one_line_naming_file_and_place(case: str, tmp_path: Path) -> None:
    text, place = SPEC_CASES[case]
    assert text != SPEC, "the fixture did not change the file"
    path = tmp_path / f"{case}.toml"
    path.write_text(text)
    with pytest.raises(SpecError) as info:
        load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and re.search(place, message), message
    result = CliRunner().invoke(app, ["spec", "show", "--spec", str(path)])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert lines == [f"roco: {message}"]


@pytest.mark.parametrize(
    ("data", "place"),
    [
        (b'system = "x"\n\xff\xfe', "not UTF-8 text (byte 0xff at line 2, column 1)"),
        (None, "is a directory, not a specification file"),
    ],
)
def test_unreadable_specification_files_are_one_line_too(
    data: bytes | None, place: str, tmp_path: Path
) -> None:
    path = tmp_path / "spec.toml"
    if data is None:
        path.mkdir()
    else:
        path.write_bytes(data)
    for command in (["spec", "show"], ["spec", "deadlock"], ["spec", "check"], ["spec", "verify-code"]):
        result = CliRunner().invoke(app, [*command, "--spec", str(path)])
        assert result.exit_code == 2, result.output
        assert result.output.strip() == f"roco: {path}: {place}"


SCENARIO_CASES: dict[str, tuple[str | bytes, str]] = {
    "syntax": ('name = "x"\n[[steps]\nsay = "a"\n', r"not TOML: .*at line 2, column \d+"),
    "type": ('name = "x"\n[[steps]]\nsay = 3\n', r"\$\.steps\[0\]\.say"),
    "unknown_field": (
        'name = "x"\n[[steps]]\nsay = "a"\nshout = true\n',
        r"unknown field `shout` - at `\$\.steps\[0\]`",
    ),
    "unknown_agent": ('name = "x"\n[[steps]]\nrestart = "a_zz"\n', r"step 1: no agent 'a_zz'"),
    "not_utf8": (b'name = "\xff"\n', r"not UTF-8 text \(byte 0xff at line 1, column 9\)"),
}


@pytest.mark.parametrize("case", sorted(SCENARIO_CASES))
def test_a_malformed_scenario_file_is_one_line_naming_file_and_place(case: str, tmp_path: Path) -> None:
    text, place = SCENARIO_CASES[case]
    path = tmp_path / f"{case}.toml"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and re.search(place, message), message
    result = CliRunner().invoke(app, ["scenario", str(path), "--runs-dir", str(tmp_path / "runs")])
    assert result.exit_code == 2 and result.output.strip() == f"roco: {message}"


@pytest.mark.parametrize("content", [b"{not json", b'{"endpoint": 3}', b"\xff\xfe"])
def test_a_malformed_fleet_state_file_is_one_line(content: bytes, tmp_path: Path) -> None:
    (tmp_path / FLEET_FILE).write_bytes(content)
    for command in (["down"], ["status", "--counters-timeout", "0"]):
        result = CliRunner().invoke(app, [*command, "--runs-dir", str(tmp_path)])
        assert result.exit_code == 2, result.output
        (line,) = result.output.strip().splitlines()
        assert line.startswith(f"roco: {tmp_path / FLEET_FILE}: not a fleet state file: ")
