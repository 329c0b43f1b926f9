"""``roco chaos --hosts`` refuses what it cannot do in one line, exit 2, before making anything:
no way to make the two hosts here, access control turned off, a service one host has
(``router``) but two hosts do not."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app


def _run(args: list[str], tmp_path: Path) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["chaos", "--hosts", *args, "--runs-dir", str(tmp_path / "runs")])
    return result.exit_code, result.output


def test_without_namespaces_it_says_why_in_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    why = "network namespaces need root (ip netns add)"
    monkeypatch.setattr("services.hosts.netns.unavailable", lambda: why)
    code, out = _run([], tmp_path)
    assert code == 2 and out.strip().splitlines() == [f"roco: --hosts cannot make two hosts here: {why}"]
    assert not (tmp_path / "runs").exists()


def test_without_nftables_it_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from services.hosts import netns

    monkeypatch.setattr(netns.os, "geteuid", lambda: 0)
    monkeypatch.setattr(netns.shutil, "which", lambda name: None if name == "nft" else f"/usr/sbin/{name}")
    code, out = _run([], tmp_path)
    assert code == 2 and out.strip().splitlines() == [
        "roco: --hosts cannot make two hosts here: nftables' nft is not installed (apt-get install nftables)"
    ]
    assert not (tmp_path / "runs").exists()


def test_access_control_cannot_be_turned_off_and_two_hosts_have_no_single_router(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("services.hosts.netns.unavailable", lambda: None)
    code, out = _run(["--no-acl"], tmp_path)
    assert code == 2 and "always runs with access control and mutual TLS" in out
    code, out = _run(["--services", "router"], tmp_path)
    assert code == 2 and "cannot fault router" in out and "router_brain, router_robot, link" in out
    assert not (tmp_path / "runs").exists()


def test_the_link_is_shaped_only_with_hosts_and_only_as_it_can_be(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for option in (["--delay-ms", "5"], ["--cut", "35,40"]):
        result = CliRunner().invoke(app, ["chaos", *option, "--runs-dir", str(tmp_path / "runs")])
        assert result.exit_code == 2 and "the link of --hosts" in result.output
    monkeypatch.setattr("services.hosts.netns.unavailable", lambda: None)
    code, out = _run(["--delay-ms", "2", "--jitter-ms", "5"], tmp_path)
    assert code == 2 and "need 0 ≤ jitter ≤ delay" in out
    code, out = _run(["--cut", "40,35"], tmp_path)
    assert code == 2 and out.strip() == "roco: --cut needs 0 <= MIN <= MAX <= 3600, not '40,35'"
    assert not (tmp_path / "runs").exists()


def test_a_fault_of_ag_ex_is_refused_while_the_kitchen_lives_in_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``ROCO_WORLD=loop`` (the physics inside ag_ex's loop, to measure the split): a fault of
    ag_ex would start the kitchen anew, so roco chaos says so and runs nothing."""
    monkeypatch.setenv("ROCO_WORLD", "loop")
    runs = tmp_path / "runs"
    result = CliRunner().invoke(app, ["chaos", "--runs-dir", str(runs)])
    assert result.exit_code == 2 and "ROCO_WORLD=loop keeps the kitchen in ag_ex" in result.output
    monkeypatch.setenv("ROCO_WORLD", "elsewhere")
    result = CliRunner().invoke(app, ["chaos", "--runs-dir", str(runs)])
    assert result.exit_code == 2 and "ROCO_WORLD='elsewhere': expected one of process, loop" in result.output
    assert not runs.exists()
