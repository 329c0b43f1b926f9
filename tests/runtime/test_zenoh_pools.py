"""Every roco client session runs on Zenoh's runtime pools as services/runtime/transport.py sets
them (``RUNTIME_POOLS``: one application thread, one transmitting thread), a router on Zenoh's
own, and none uses Zenoh's shared-memory transport, whose watchdog would wake each process 20
times a second (docs/benchmarks.md, "Fewer wake-ups per communicate"). A ``ZENOH_RUNTIME`` the
user set is kept.

Sessions are opened in fresh interpreters (the pools are built at a process's first session)
against a router on a free loopback port, started from this process with the clients' setting
in its environment, as `roco up` starts one."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.fleet.launcher import Fleet, free_port
from services.runtime.zenoh_config import (
    ENV_RUNTIME,
    RUNTIME_POOLS,
    client_config,
    router_config,
    use_runtime_pools,
)
from tests.support.router import router_fleet

ROOT = Path(__file__).resolve().parents[2]

THREADS = """
import os, sys, threading
from services.runtime.transport import ZenohTransport
t, other = ZenohTransport([sys.argv[1]]), ZenohTransport([sys.argv[1]])
got = threading.Event()
t.subscribe("roco/fipa/probe/**", lambda key, payload: got.set())
other.subscribe("roco/fipa/probe/**", lambda key, payload: None)
# from one session to the other through the router: the pools have sent and received (the
# router may get a put before it knows the subscriber: sent again until one arrives)
while not got.is_set():
    other.publish("roco/fipa/probe/x", b"")
    got.wait(0.05)
names = sorted(open(f"/proc/self/task/{tid}/comm").read().strip() for tid in os.listdir("/proc/self/task"))
print(",".join(names))
other.close()
t.close()
"""


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    use_runtime_pools()  # as in a client process that starts a router
    yield from router_fleet(tmp_path_factory, "pools")


@pytest.fixture
def router(fleet: Fleet) -> str:
    return fleet.endpoint


def _zenoh_names(names: set[str]) -> set[str]:
    return {n for n in names if n.split("-")[0] in {"app", "tx", "rx", "net", "acc"}}


def _python(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """A fresh interpreter run with ``args`` in the project's folder, its output kept."""
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60, check=False
    )


def _zenoh_threads(endpoint: str, env: dict[str, str]) -> set[str]:
    """Names of the Zenoh runtime's threads in a fresh process that opened a transport."""
    done = _python(["-c", THREADS, endpoint], env)
    assert done.returncode == 0, done.stderr[-2000:]
    return _zenoh_names(set(done.stdout.strip().splitlines()[-1].split(",")))


def test_a_session_runs_on_one_application_and_one_transmitting_pool(router: str) -> None:
    env = {k: v for k, v in os.environ.items() if k != ENV_RUNTIME}
    threads = _zenoh_threads(router, env)
    assert "tx-0" in threads and "app-0" in threads
    assert not {n for n in threads if n.startswith(("rx-", "net-", "acc-"))}, threads


def test_a_router_keeps_zenohs_own_pools(fleet: Fleet) -> None:
    """Started from a client process, it does not take the clients' single receiving thread
    (one link waiting for room would stop it reading every other)."""
    _zenoh_threads(fleet.endpoint, dict(os.environ))  # a client's transport: the router's pools are lazy
    tasks = Path(f"/proc/{fleet.pids()['router']}/task")
    threads = _zenoh_names({(t / "comm").read_text().strip() for t in tasks.iterdir()})
    assert {"rx-0", "rx-1", "net-0"} <= threads, threads


def test_a_runtime_setting_of_the_user_is_kept(router: str) -> None:
    env = {**os.environ, ENV_RUNTIME: "()"}  # Zenoh's own defaults
    threads = _zenoh_threads(router, env)
    assert {"rx-0", "net-0"} <= threads, threads


def test_no_configuration_uses_shared_memory() -> None:
    for conf in (client_config(["tcp/127.0.0.1:7447"]), router_config(["tcp/127.0.0.1:7447"])):
        assert json.loads(conf.get_json("transport/shared_memory/enabled")) is False
    assert "handover: app" in RUNTIME_POOLS


def test_a_runtime_setting_zenoh_cannot_read_stops_a_process_with_one_line_naming_it() -> None:
    """Zenoh panics on it (and prints its own backtrace first); the process ends with exit code
    2 and a last line that names the variable."""
    env = {**os.environ, ENV_RUNTIME: "(rx: oops"}
    done = _python(["-m", "services.runtime.router", "--listen", f"tcp/127.0.0.1:{free_port()}"], env)
    assert done.returncode == 2, done.stderr[-2000:]
    assert (
        done.stderr.strip()
        .splitlines()[-1]
        .startswith("roco router: ZENOH_RUNTIME='(rx: oops': Zenoh cannot read it")
    )
