"""A service with its own credentials only (a container of deploy/compose.yaml: the CA's
certificate and its identity's folder, nothing else) connects, holds its token and passes its
health check as itself, against a real router with mutual TLS on a free loopback port; a name
whose credentials it lacks is not reached with another's."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.health import check
from services.runtime.transport import ZenohTransport
from services.security import certs
from services.security.context import register


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    run_dir = tmp_path_factory.mktemp("own")
    (run_dir / "logs").mkdir()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=True)
    fleet.start_router()
    yield fleet
    fleet.stop()
    register(fleet.endpoint, None)


def own_folder(full: Path, name: str, into: Path) -> Path:
    """What ``name``'s container mounts at /certs."""
    into.mkdir()
    shutil.copy2(full / certs.CA_CERT, into / certs.CA_CERT)
    shutil.copytree(full / name, into / name)
    return into


def test_an_agent_with_only_its_own_credentials_is_healthy_as_itself(fleet: Fleet, tmp_path: Path) -> None:
    assert fleet.security is not None and fleet.endpoint.startswith("tls/")
    mine = own_folder(fleet.security, "a_pl", tmp_path / "certs")
    register(fleet.endpoint, mine)
    try:
        ok, line = check("a_pl", router=fleet.endpoint, timeout=2.0)
        assert not ok and line == f"a_pl absent at {fleet.endpoint}", line  # asked, not there yet
        agent = ZenohTransport([fleet.endpoint], identity="a_pl", links=None)  # as services/runtime/main.py
        try:
            token = agent.session.liveliness().declare_token(keys.alive_key("a_pl"))
            ok, line = check("a_pl", router=fleet.endpoint, timeout=5.0)
            assert ok and line == f"a_pl alive at {fleet.endpoint}", line
            token.undeclare()
        finally:
            agent.close()
        ok, line = check("a_km", router=fleet.endpoint, timeout=2.0)
        assert not ok and line.startswith("a_km unknown: ") and "no credentials for 'operator'" in line, line
    finally:
        register(fleet.endpoint, fleet.security)
