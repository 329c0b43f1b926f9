"""Without the Rerun CLI's binary (roco's runtime image leaves it out: deploy/Dockerfile), what
would run it says so in one line: the merge of a run's parts logs it and returns None, and
the viewer refuses to start with it."""

from __future__ import annotations

import importlib.machinery
import logging
from pathlib import Path

import pytest

from services.viewer import recording, view


def _cli_package(monkeypatch: pytest.MonkeyPatch, folder: Path, *, binary: bool) -> Path:
    """A ``rerun_cli`` package in ``folder``, with its ``rerun`` binary or without."""
    package = folder / "rerun_cli"
    package.mkdir()
    (package / "__init__.py").write_text("")
    if binary:
        (package / "rerun").write_text("#!/bin/sh\n")
    spec = importlib.machinery.ModuleSpec("rerun_cli", None, origin=str(package / "__init__.py"))
    monkeypatch.setattr(
        recording.importlib.util, "find_spec", lambda name: spec if name == "rerun_cli" else None
    )
    return package / "rerun"


def test_an_image_without_the_cli_says_so_in_one_line(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    binary = _cli_package(monkeypatch, tmp_path, binary=False)
    missing = recording.rerun_cli_missing()
    assert missing is not None and "\n" not in missing
    assert missing.startswith(f"no Rerun CLI here: {binary} is absent") and "roco-viewer" in missing
    with pytest.raises(RuntimeError, match=r"^no Rerun CLI here: "):
        view.start_viewer(None)


def test_the_merge_logs_the_missing_cli_and_runs_nothing(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    _cli_package(monkeypatch, tmp_path, binary=False)
    run_dir = tmp_path / "run"
    (run_dir / recording.PARTS_DIR).mkdir(parents=True)
    (run_dir / recording.PARTS_DIR / "a_co-1-0.rrd").write_bytes(b"")
    ran: list[object] = []
    monkeypatch.setattr(recording.subprocess, "run", lambda *a, **k: ran.append(a))
    with caplog.at_level(logging.ERROR, logger=recording.__name__):
        assert recording.merge_parts(run_dir) is None
    assert ran == []
    (line,) = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
    assert line.startswith("rerun rrd merge not run: no Rerun CLI here: ")


def test_with_the_binary_the_cli_is_there(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    _cli_package(monkeypatch, tmp_path, binary=True)
    assert recording.rerun_cli_missing() is None


def test_without_the_package(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(recording.importlib.util, "find_spec", lambda name: None)
    assert recording.rerun_cli_missing() == (
        "no Rerun CLI here: the rerun_cli package is not installed (pip install rerun-sdk)"
    )
