"""``roco gateway``'s errors: one line, non-zero exit (services/cli/gateway.py)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

from services.fleet.launcher import Fleet, free_port


def gateway(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", "gateway", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,  # no runs/.fleet.json there
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
    )


def test_no_router_is_one_line_and_exit_1(tmp_path: Path) -> None:
    done = gateway(tmp_path, "--router", f"tcp/127.0.0.1:{free_port()}", "--port", str(free_port()))
    assert done.returncode == 1
    assert done.stderr.startswith("roco: gateway: no router answers at tcp/127.0.0.1:")
    assert done.stderr.count("\n") == 1


def test_a_spec_without_external_role_is_refused(tmp_path: Path) -> None:
    """The sorting cell has no external role: nobody of another platform may come in."""
    from tests.support.cell_fleet import CELL

    done = gateway(tmp_path, "--spec", str(CELL), "--port", str(free_port()))
    assert done.returncode == 1, done.stderr
    assert done.stderr == f"roco: gateway: {CELL}: no external role ([[externals]]): nobody may come in\n"


def test_a_spec_that_does_not_load_is_one_line(tmp_path: Path) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text('system = "x"\n')
    done = gateway(tmp_path, "--spec", str(spec), "--port", str(free_port()))
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith(f"roco: {spec}: ")


def test_a_port_in_use_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=False)
    fleet.start_router()
    busy = socket.socket()
    try:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        done = gateway(tmp_path, "--router", fleet.endpoint, "--port", str(port))
    finally:
        busy.close()
        fleet.stop()
    assert done.returncode == 1 and done.stderr.startswith(
        f"roco: gateway: cannot listen on 127.0.0.1:{port}"
    )


def test_a_malformed_platform_binding_is_one_line(tmp_path: Path) -> None:
    done = gateway(tmp_path, "--port", str(free_port()), "--platform", "host:1099/JADE")
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("roco: gateway: --platform 'host:1099/JADE': expected PLATFORM=URL")
    done = gateway(tmp_path, "--port", str(free_port()), "--platform", "host:1099/JADE=https://h:1/acc")
    assert done.returncode == 1 and "only http://host:port/… addresses" in done.stderr, done.stderr
