"""Health probe for scripts and people: ``python -m services.runtime.health NAME``.

Exit 0 when NAME is healthy, else 1; either way one line on stdout saying why. Exit 2 on a
usage error. (The compose fleet's own health checks read each service's ready file instead,
shared/ready_file.py: they start no interpreter and open no connection.)

- an agent or the traffic recorder (``a_km``, ``recorder``, …): healthy when its liveliness
  token ``roco/alive/NAME`` is visible through the router (Zenoh's white pages, the query of
  ``roco status`` on that one key, as identity NAME where the credentials hold it). The
  router is ``--router EP``, else ``ROCO_ROUTER`` (its first endpoint), else
  ``tcp/127.0.0.1:7447``;
- ``router``: healthy when the router's TCP endpoint accepts a connection (no Zenoh session
  is opened, so a probe costs the router nothing);
- with ``--tcp HOST:PORT`` (repeatable; e.g. the Rerun viewer): healthy when every one of
  those ports accepts a connection, whatever NAME is.

Zenoh is imported only for the liveliness check, so the TCP probes start in a few tens of ms.
"""

from __future__ import annotations

import argparse
import socket
import sys

ROUTER = "router"


def endpoint_address(endpoint: str) -> tuple[str, int]:
    """Host and port of a Zenoh TCP endpoint (``tcp/HOST:PORT``, ``tcp/[::1]:PORT``; ``tls/…``
    runs over TCP too); a bare ``HOST:PORT`` is accepted too. Raises ValueError otherwise."""
    proto, sep, rest = endpoint.partition("/")
    if not sep:
        proto, rest = "tcp", endpoint
    if proto not in ("tcp", "tls"):
        raise ValueError(f"not a TCP endpoint: {endpoint!r}")
    rest = rest.split("#", 1)[0].split("?", 1)[0]  # Zenoh endpoint metadata / config
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ValueError(f"not HOST:PORT: {endpoint!r}")
    return host.strip("[]"), int(port)


def tcp_open(host: str, port: int, timeout: float) -> str | None:
    """None when ``host:port`` accepts a TCP connection within ``timeout`` s, else why not."""
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return None
    except OSError as exc:
        return exc.strerror or str(exc) or type(exc).__name__


def check_tcp(name: str, addresses: list[str], timeout: float) -> tuple[bool, str]:
    """Whether every ``HOST:PORT`` (or ``tcp/HOST:PORT``) accepts a connection."""
    for address in addresses:
        host, port = endpoint_address(address)
        why = tcp_open(host, port, timeout)
        if why is not None:
            return False, f"{name} unhealthy: {host}:{port}: {why}"
    return True, f"{name} healthy: {', '.join(addresses)} accept connections"


def check_alive(name: str, endpoint: str, timeout: float) -> tuple[bool, str]:
    """Whether ``name``'s liveliness token is visible through the router at ``endpoint``: a
    liveliness query on ``roco/alive/NAME`` alone, as identity ``name`` when the credentials
    folder holds it (a container holds only its own service's, deploy/compose.yaml; the ACL lets
    an identity ask for its own token, services/spec_check/acl.py), else as the default
    identity (``ROCO_IDENTITY``, else ``operator``)."""
    from services.runtime.session import alive_agents, open_client
    from services.security.folder import CredentialError

    try:
        try:
            session = open_client(endpoint, identity=name)
        except CredentialError:
            session = open_client(endpoint)
    except CredentialError as exc:
        return False, f"{name} unknown: {exc}"
    except Exception:  # zenoh.ZError: no router answers
        return False, f"{name} unknown: no router answers at {endpoint}"
    try:
        alive = alive_agents(session, timeout=timeout, only=name)
    finally:
        session.close()
    if name in alive:
        return True, f"{name} alive at {endpoint}"
    return False, f"{name} absent at {endpoint}"


def check(
    name: str, *, router: str | None = None, tcp: list[str] | None = None, timeout: float = 2.0
) -> tuple[bool, str]:
    """The probe itself: ``(healthy, one line)``. Raises ValueError on a malformed address."""
    from shared.settings import Settings  # not at the top: a TCP probe starts without msgspec

    endpoint = router or Settings.from_env(only=("router",)).router[0]
    if tcp:
        return check_tcp(name, tcp, timeout)
    if name == ROUTER:
        return check_tcp(name, [endpoint], timeout)
    return check_alive(name, endpoint, timeout)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m services.runtime.health",
        description="Exit 0 when NAME is healthy (liveliness token roco/alive/NAME; router: TCP connect).",
    )
    parser.add_argument("name", metavar="NAME", help="an agent, 'recorder', 'router', or any name with --tcp")
    parser.add_argument(
        "--router", metavar="EP", help="router endpoint (default: ROCO_ROUTER, tcp/127.0.0.1:7447)"
    )
    parser.add_argument(
        "--tcp", metavar="HOST:PORT", action="append", help="check that this port accepts connections instead"
    )
    parser.add_argument("--timeout", type=float, default=2.0, help="seconds per check (default 2)")
    args = parser.parse_args(argv)
    try:
        ok, line = check(args.name, router=args.router, tcp=args.tcp, timeout=args.timeout)
    except ValueError as exc:
        print(f"roco health: {exc}", file=sys.stderr)
        return 2
    print(line, flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
