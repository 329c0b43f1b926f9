"""An embedded Zenoh router for tests that forge traffic: a free loopback port (explicit
endpoint, no multicast), without access control unless asked (tested in tests/security/)."""

from __future__ import annotations

from collections.abc import Generator, Iterator

import pytest

from services.fleet.launcher import Fleet, free_port
from services.security.context import register


def router_fleet(
    tmp_path_factory: pytest.TempPathFactory, name: str, *, acl: bool = False, tls: bool = False
) -> Generator[Fleet, None, None]:
    """Yield a fleet of only a router, started in a fresh folder ``name`` (``acl``/``tls``: as
    ``Fleet``'s); stop it after and forget its credentials."""
    run_dir = tmp_path_factory.mktemp(name)
    (run_dir / "logs").mkdir()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=acl, tls=tls)
    fleet.start_router()
    try:
        yield fleet
    finally:
        fleet.stop()
        register(fleet.endpoint, None)


def embedded_router(tmp_path_factory: pytest.TempPathFactory, name: str) -> Iterator[str]:
    """Yield the endpoint of a router started in a fresh folder ``name``; stop it after."""
    fleets = router_fleet(tmp_path_factory, name)
    fleet = next(fleets)
    try:
        yield fleet.endpoint
    finally:
        fleets.close()  # the router stopped
