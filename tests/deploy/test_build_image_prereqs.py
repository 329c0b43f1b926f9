"""scripts/build_image.sh names a missing prerequisite before any phase takes time: no engine
answering, or no debootstrap where the base must be made (no python:3.11-slim here or
pullable). A stand-in ``docker`` (``DOCKER``) answers as such an engine would; nothing is built."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "build_image.sh"
BASH = shutil.which("bash") or "bash"
pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")


def _docker(tmp_path: Path, engine: bool) -> Path:
    """A ``docker`` whose engine answers (``version``) or not; it has no image and pulls none."""
    fake = tmp_path / "docker"
    fake.write_text(f'#!/bin/sh\ncase "$1" in version) exit {0 if engine else 1} ;; esac\nexit 1\n')
    fake.chmod(0o755)
    return fake


def _build(tmp_path: Path, engine: bool, path: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "DOCKER": str(_docker(tmp_path, engine)), "PATH": path, "PYTHON": "false"}
    return subprocess.run(
        [BASH, str(SCRIPT)], capture_output=True, text=True, env=env, timeout=60, check=False
    )


def test_no_engine_is_named_first_with_how_to_start_it(tmp_path: Path) -> None:
    done = _build(tmp_path, engine=False, path=os.environ["PATH"])
    assert done.returncode == 1
    assert "no Docker engine answers" in done.stderr and "service docker start, or dockerd &" in done.stderr
    assert "phase wheelhouse" not in done.stdout + done.stderr


def test_no_debootstrap_is_named_before_the_wheelhouse(tmp_path: Path) -> None:
    bare = tmp_path / "bin"
    bare.mkdir()
    for tool in (
        "sh",
        "cat",
        "sha256sum",
        "cut",
        "printf",
        "mktemp",
        "rm",
        "date",
        "timeout",
        "id",
        "dirname",
        "seq",
    ):
        found = shutil.which(tool)
        if found is not None:
            (bare / tool).symlink_to(found)
    done = _build(tmp_path, engine=True, path=str(bare))  # no debootstrap on this PATH
    assert done.returncode == 1, done.stdout + done.stderr
    assert "needs debootstrap (apt-get install debootstrap)" in done.stderr
    assert "phase wheelhouse" not in done.stdout + done.stderr
