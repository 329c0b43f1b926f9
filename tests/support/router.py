"""An embedded Zenoh router for tests that forge traffic: a free loopback port (explicit
endpoint, no multicast), no access control (tested in tests/security/)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from services.fleet.launcher import Fleet, free_port


def router_fleet(tmp_path_factory: pytest.TempPathFactory, name: str) -> Iterator[Fleet]:
    """Yield a fleet of only a router, started in a fresh folder ``name``; stop it after."""
    run_dir = tmp_path_factory.mktemp(name)
    (run_dir / "logs").mkdir()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=False)
    fleet.start_router()
    try:
        yield fleet
    finally:
        fleet.stop()


def embedded_router(tmp_path_factory: pytest.TempPathFactory, name: str) -> Iterator[str]:
    """Yield the endpoint of a router started in a fresh folder ``name``; stop it after."""
    fleets = router_fleet(tmp_path_factory, name)
    fleet = next(fleets)
    try:
        yield fleet.endpoint
    finally:
        fleets.close()  # the router stopped
