"""A bag of ``roco export`` in place of its run folder: ``roco spec verify`` gives the same
verdict on the traffic of a real pour (tests/spec_check/two_hosts_run), ``roco report`` reads
it and says what the bag lacks; the command's refusals are one ``roco:`` line each."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.report.build import build_report
from services.ros2 import bag, messages
from services.ros2.export import export_run
from services.spec_check.conformance import verify_report

pytest.importorskip("rosbags", reason="the ros2 extra's rosbags is not installed")
pytest.importorskip("mcap", reason="the ros2 extra's mcap is not installed")

REAL_POUR = Path(__file__).parents[1] / "spec_check" / "two_hosts_run"
"""The traffic record of a real pour (307 communicates; its README says how it was made)."""

runner = CliRunner()


@pytest.fixture
def pour(tmp_path: Path) -> Path:
    run = tmp_path / "run"
    shutil.copytree(REAL_POUR, run)
    return run


def without_path(text: str) -> list[str]:
    """The verify report's lines, the first (naming the folder) and the bag's note left out."""
    return [line for line in text.splitlines()[1:] if bag.MISSING not in line]


def test_verify_verdict_is_the_run_folders(pour: Path, tmp_path: Path) -> None:
    export_run(pour, tmp_path / "bag")
    ok_run, text_run = verify_report(pour)
    ok_bag, text_bag = verify_report(tmp_path / "bag")
    assert ok_bag == ok_run
    assert without_path(text_bag) == without_path(text_run)
    assert "communicates: 307" in text_bag
    assert bag.MISSING in text_bag


def test_verify_verdict_follows_a_violation(pour: Path, tmp_path: Path) -> None:
    """A communicate on a channel its sender may not use, in the run: the bag says so too."""
    lines = (pour / "traffic.jsonl").read_text().splitlines()
    lines[5] = lines[5].replace('"channel":"C', '"channel":"X', 1)
    (pour / "traffic.jsonl").write_text("\n".join(lines) + "\n")
    export_run(pour, tmp_path / "bag")
    ok_run, text_run = verify_report(pour)
    ok_bag, text_bag = verify_report(tmp_path / "bag")
    assert not ok_run and not ok_bag
    assert without_path(text_bag) == without_path(text_run)


def test_report_reads_a_bag(pour: Path, tmp_path: Path) -> None:
    export_run(pour, tmp_path / "bag")
    report = build_report(tmp_path / "bag")
    assert any(bag.MISSING in n for n in report.notes)
    assert report == build_report(tmp_path / "bag")
    result = runner.invoke(app, ["report", str(tmp_path / "bag")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "bag" / "report.md").is_file()


def test_cli_exports_and_verify_takes_the_bag(pour: Path, tmp_path: Path) -> None:
    result = runner.invoke(app, ["export", str(pour), "--mcap"])
    assert result.exit_code == 0, result.output
    assert "/roco/traffic" in result.output and "recording.rrd" in result.output
    assert bag.is_bag(pour / "rosbag2")
    verified = runner.invoke(app, ["spec", "verify", str(pour / "rosbag2")])
    assert verified.exit_code == runner.invoke(app, ["spec", "verify", str(pour)]).exit_code


def test_cli_refusals_are_one_line(pour: Path, tmp_path: Path) -> None:
    no_format = runner.invoke(app, ["export", str(pour)])
    taken = runner.invoke(app, ["export", str(pour), str(pour), "--mcap"])
    not_run = runner.invoke(app, ["export", str(tmp_path), "--mcap"])
    for result in (no_format, taken, not_run):
        assert result.exit_code == 2
        assert len(result.output.strip().splitlines()) == 1 and result.output.startswith("roco: ")


def test_missing_extra_is_one_line(pour: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "mcap.writer", None)
    result = runner.invoke(app, ["export", str(pour), str(tmp_path / "bag"), "--mcap"])
    assert result.exit_code == 2 and result.output.startswith("roco: writing MCAP needs the ros2 extra")
    monkeypatch.setitem(sys.modules, "rosbags.typesys", None)
    messages.typestore.cache_clear()
    try:
        result = runner.invoke(app, ["export", str(pour), str(tmp_path / "bag2"), "--mcap"])
    finally:
        monkeypatch.undo()
        messages.typestore.cache_clear()
    assert result.exit_code == 2 and result.output.startswith("roco: ROS 2 formats need the ros2 extra")
    assert len(result.output.strip().splitlines()) == 1
