"""What a roco service writes to standard output, where ``docker compose logs`` reads it
(docs/deploy.md, "Logs and health"): an agent's (and the recorder's) log lines, the same as in
the run folder's ``logs/NAME.log``, with ``ROCO_LOG_STDOUT=1`` (services/runtime/main.py
``setup_logging``); the router's Zenoh log at INFO, the DEBUG and TRACE lines its refusal watch
reads not passed on (services/runtime/zenoh_log.py), and its ready file while it listens."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.fleet.launcher import Fleet, free_port
from services.runtime.session import open_client
from services.runtime.zenoh_log import least_level, level_of, passes
from tests.support.fresh import run_python
from tests.support.lines import wait_until

LOGS = (
    "import logging; from services.runtime.main import setup_logging; setup_logging('a_km'); "
    "logging.getLogger('a_km').info('started (pid %d)', 42); "
    "logging.getLogger('a_km').warning('a line\\nthat reads as two')"
)
LINES = ("a_km INFO started (pid 42)", "a_km WARNING a line\\nthat reads as two")


def run_logs(tmp_path: Path, **env: str) -> tuple[list[str], list[str], list[str]]:
    """Lines on stdout, on stderr and in ``logs/a_km.log`` of :data:`LOGS` run in a fresh
    interpreter with the environment ``env`` (the ``ROCO_*`` of this process left out)."""
    saved = {k: os.environ.pop(k) for k in list(os.environ) if k.startswith("ROCO_")}
    try:
        os.environ.update(env)
        done = run_python(LOGS, timeout=60)
    finally:
        for k in env:
            os.environ.pop(k, None)
        os.environ.update(saved)
    assert done.returncode == 0, done.stderr
    log = tmp_path / "logs" / "a_km.log"
    in_file = log.read_text().splitlines() if log.exists() else []
    return done.stdout.splitlines(), done.stderr.splitlines(), in_file


def without_time(lines: list[str]) -> list[str]:
    return [line.split(" ", 2)[2] for line in lines]


def test_an_agents_log_goes_to_stdout_as_well_as_its_file(tmp_path: Path) -> None:
    out, err, in_file = run_logs(tmp_path, ROCO_RUN_DIR=str(tmp_path), ROCO_LOG_STDOUT="1")
    assert without_time(out) == list(LINES) and out == in_file and err == []


def test_without_the_setting_the_log_is_in_its_file_only(tmp_path: Path) -> None:
    """A local fleet (`roco up`) keeps each process's stdout in logs/NAME.stderr: no copy there."""
    out, err, in_file = run_logs(tmp_path, ROCO_RUN_DIR=str(tmp_path))
    assert out == [] and err == [] and without_time(in_file) == list(LINES)


def test_without_a_run_folder_the_log_goes_to_one_stream(tmp_path: Path) -> None:
    out, err, in_file = run_logs(tmp_path, ROCO_LOG_STDOUT="1")
    assert without_time(out) == list(LINES) and err == [] and in_file == []
    out, err, in_file = run_logs(tmp_path)
    assert out == [] and without_time(err) == list(LINES)


ZENOH_LINES = {
    "debug": "\x1b[2m2026-11-27T05:46:55.732010Z\x1b[0m \x1b[34mDEBUG\x1b[0m ThreadId(01) "
    "\x1b[2mzenoh::net::routing::interceptor::access_control\x1b[0m\x1b[2m:\x1b[0m "
    "Access control is enabled\n",
    "warn": "2026-11-27T05:46:59.529449Z  WARN acc-0 ThreadId(05) zenoh_link_tls::unicast: "
    "tls handshake eof. Hint: increase the system open file limit.\n",
    "info": "2026-11-27T05:47:05.223304Z  INFO ThreadId(01) zenoh::net::runtime: Using ZID: b89e58ce\n",
    "trace": "2026-11-27T05:47:05.223304Z TRACE rx-0 ThreadId(08) zenoh::net::routing::interceptor::"
    "access_control: 460cf6 is authorized to Put (ingress) on roco/alive/a_km\n",
}
"""Lines of Zenoh's log as eclipse-zenoh 1.x writes them (coloured or not)."""


def test_zenohs_lines_pass_at_the_level_rust_log_names() -> None:
    assert {level: level_of(line) for level, line in ZENOH_LINES.items()} == {k: k for k in ZENOH_LINES}
    assert least_level("") == least_level("off") == "info"
    assert least_level("warn") == "warn" and least_level("warn,zenoh_link_tls=debug") == "debug"
    passed = {
        least: [k for k, line in ZENOH_LINES.items() if passes(line, least)] for least in ("info", "trace")
    }
    assert passed == {"info": ["warn", "info"], "trace": ["debug", "warn", "info", "trace"]}
    assert passes("a line of no level\n", "error")


@pytest.fixture
def router(tmp_path: Path) -> Iterator[Fleet]:
    """A router with access control (its refusal watch on) and a ready file, no RUST_LOG."""
    rust_log = os.environ.pop("RUST_LOG", None)
    fleet = Fleet(
        tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=True, env={"ROCO_READY_FILE": str(tmp_path / "ready")}
    )
    try:
        yield fleet
    finally:
        fleet.stop()
        if rust_log is not None:
            os.environ["RUST_LOG"] = rust_log


def test_the_routers_log_is_at_info_and_it_is_ready_while_it_listens(router: Fleet, tmp_path: Path) -> None:
    (tmp_path / "logs").mkdir(exist_ok=True)
    router.start_router()
    session = open_client(router.endpoint, wait_for_router=True, identity="a_km")  # as an agent's session
    session.close()
    wait_until((tmp_path / "ready").exists, 10, "the router's ready file")
    ready = (tmp_path / "ready").read_text()
    assert ready.startswith("roco router ") and f"listening on {router.endpoint}" in ready
    router.stop()
    assert not (tmp_path / "ready").exists()
    lines = (tmp_path / "logs" / "router.stderr").read_text().splitlines()
    levels = {level_of(line) for line in lines}
    assert "info" in levels and not levels & {"debug", "trace"}, lines
    assert not any("\x1b[" in line for line in lines)  # no terminal colours in a log file
    assert any(line.startswith("roco router ") and "listening on" in line for line in lines)
