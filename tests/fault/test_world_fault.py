"""The world process among a local fleet's services (services/fault/process.py): named and
started as the launcher does, and ``start`` waits until the new world names a new link."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.fault.process import FaultError, _wait_world, local_services
from services.fleet.launcher import service_args
from services.spec.model import default_spec
from velma.world.files import LINK_FILE, write_whole
from velma.world.mode import WORLD_SERVICE


def test_the_world_is_a_service_of_a_local_fleet_run_as_the_launcher_runs_it() -> None:
    assert WORLD_SERVICE in local_services(default_spec())
    assert service_args(WORLD_SERVICE, "tcp/127.0.0.1:7447") == ["-m", "velma.world"]


def test_a_started_world_is_back_once_it_names_a_new_link(tmp_path: Path) -> None:
    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    write_whole(tmp_path / LINK_FILE, b"psm_old\n")  # a killed world's name stays behind
    with pytest.raises(FaultError, match="world exited with code 0"):
        _wait_world(tmp_path, "psm_old", ended, timeout=30)
    write_whole(tmp_path / LINK_FILE, b"psm_new\n")
    _wait_world(tmp_path, "psm_old", ended, timeout=30)  # named: back, whatever came after
