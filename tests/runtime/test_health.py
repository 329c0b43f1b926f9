"""The health probe (`python -m services.runtime.health`) against a real router on a loopback
port: the router by TCP, an agent by its liveliness token, any port with --tcp."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.health import check, endpoint_address, main
from services.runtime.session import open_client


@pytest.fixture(scope="module")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, zenoh.Session]]:
    run_dir: Path = tmp_path_factory.mktemp("health")
    (run_dir / "logs").mkdir()
    # forged traffic and tokens from the test: no access control (tested in tests/security/)
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=False)
    fleet.start_router()
    session = open_client(fleet.endpoint)
    try:
        yield fleet.endpoint, session
    finally:
        session.close()
        fleet.stop()


def test_endpoint_address() -> None:
    assert endpoint_address("tcp/router:7447") == ("router", 7447)
    assert endpoint_address("tcp/[::1]:7447") == ("::1", 7447)
    assert endpoint_address("127.0.0.1:9090") == ("127.0.0.1", 9090)
    for bad in ("udp/127.0.0.1:7447", "tcp/router", "tcp/:7447"):
        with pytest.raises(ValueError):
            endpoint_address(bad)


def test_router_by_tcp(router: tuple[str, zenoh.Session]) -> None:
    endpoint, _ = router
    ok, line = check("router", router=endpoint)
    assert ok and line.startswith("router healthy")
    ok, line = check("router", router=f"tcp/127.0.0.1:{free_port()}", timeout=0.5)
    assert not ok and line.startswith("router unhealthy")


def test_agent_by_liveliness_token(
    router: tuple[str, zenoh.Session], capsys: pytest.CaptureFixture[str]
) -> None:
    endpoint, session = router
    assert main(["a_probe", "--router", endpoint]) == 1
    out = capsys.readouterr().out
    assert out.startswith("a_probe absent at ") and out.count("\n") == 1
    token = session.liveliness().declare_token(keys.alive_key("a_probe"))
    # the token's withdrawal reaches the router asynchronously: a second client sees it go
    # (through the router) before the probe asks again
    watcher = open_client(endpoint)
    gone = threading.Event()
    watcher.liveliness().declare_subscriber(
        keys.alive_key("a_probe"),
        lambda sample: gone.set() if sample.kind == zenoh.SampleKind.DELETE else None,
    )
    try:
        assert main(["a_probe", "--router", endpoint]) == 0
        assert capsys.readouterr().out == f"a_probe alive at {endpoint}\n"
    finally:
        token.undeclare()
    try:
        assert gone.wait(10), "the router never reported a_probe's token withdrawn"
    finally:
        watcher.close()
    assert check("a_probe", router=endpoint)[0] is False


def test_no_router(capsys: pytest.CaptureFixture[str]) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    assert main(["a_km", "--router", endpoint]) == 1
    assert capsys.readouterr().out == f"a_km unknown: no router answers at {endpoint}\n"


def test_tcp_ports(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        port = listening.getsockname()[1]
        assert main(["viewer", "--tcp", f"127.0.0.1:{port}"]) == 0
        assert main(["viewer", "--tcp", f"127.0.0.1:{port}", "--tcp", f"127.0.0.1:{free_port()}"]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("viewer healthy") and lines[1].startswith("viewer unhealthy")
    assert main(["viewer", "--tcp", "nowhere"]) == 2


def test_module_entry_point_uses_roco_router(router: tuple[str, zenoh.Session]) -> None:
    endpoint, session = router
    with session.liveliness().declare_token(keys.alive_key("a_entry")):
        done = subprocess.run(
            [sys.executable, "-m", "services.runtime.health", "a_entry"],
            capture_output=True,
            text=True,
            timeout=60,
            env={"ROCO_ROUTER": endpoint, "PATH": "/usr/bin:/bin"},
        )
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout == f"a_entry alive at {endpoint}\n"
