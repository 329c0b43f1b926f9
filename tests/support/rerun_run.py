"""A run folder for a test that records with Rerun (services/viewer)."""

from __future__ import annotations

from pathlib import Path

import pytest


def rerun_run_dir(folder: Path, monkeypatch: pytest.MonkeyPatch, *unset: str) -> Path:
    """``folder``, created, as the folder of a run with Rerun on (``ROCO_RERUN=1``,
    ``ROCO_RUN_DIR``); no recording id or viewer to connect to is taken from the environment
    (``ROCO_RERUN_ID``, ``ROCO_RERUN_CONNECT`` unset), nor the variables ``unset``."""
    folder.mkdir()
    monkeypatch.setenv("ROCO_RERUN", "1")
    monkeypatch.setenv("ROCO_RUN_DIR", str(folder))
    for name in ("ROCO_RERUN_ID", "ROCO_RERUN_CONNECT", *unset):
        monkeypatch.delenv(name, raising=False)
    return folder
