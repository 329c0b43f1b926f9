"""``roco gateway``: run the ACL gateway (services/gateway/bridge.py) in the foreground.

It opens a Zenoh session to the fleet's router as the identity ``gateway`` (with the fleet's
credentials when it has access control: services/security/context.py), serves the FIPA HTTP
message transport (FIPA SC00084) on ``host:port`` and tells foreign platforms to post to
``address`` (default ``http://<host>:<port>/acc``). It prints one line when it is ready, and
a line of counters when it stops (Ctrl-C, SIGTERM). Its log is one line per event
(services/runtime/log_format.py), on stderr.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path

from services.gateway.bridge import GATEWAY, open_gateway
from services.gateway.http_mtp import MTPError, check_address
from services.runtime.foreground import Counters, run_until_stopped
from services.runtime.polling import max_poll_us
from services.runtime.session import listening, port_in_use, refusal
from services.runtime.transport import ZenohTransport
from services.security.context import security_for
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, load
from shared.settings import GATEWAY_PORT


class GatewayError(Exception):
    """The gateway cannot start; the message is one line."""


@dataclass(frozen=True)
class GatewayConfig:
    """What ``roco gateway`` is given: the router ``endpoint``, the ``host`` and ``port`` the
    HTTP server listens on, the ``address`` advertised to foreign platforms (None: derived from
    host and port), the specification file ``spec`` and ``platforms``: ``PLATFORM=URL[,URL…]``
    each, the addresses every agent ``…@PLATFORM`` is answered at (services/gateway/identity.py)."""

    endpoint: str
    host: str = "127.0.0.1"
    port: int = GATEWAY_PORT
    address: str | None = None
    spec: Path = DEFAULT_SPEC
    platforms: tuple[str, ...] = ()


def parse_platforms(items: tuple[str, ...]) -> dict[str, tuple[str, ...]]:
    """``PLATFORM=URL[,URL…]`` items as platform → addresses. Raises GatewayError (one line)
    for an item without ``=``, with no platform or address, or with an address that is no
    ``http://`` URL."""
    platforms: dict[str, tuple[str, ...]] = {}
    for item in items:
        platform, sep, urls = item.partition("=")
        addresses = tuple(u.strip() for u in urls.split(",") if u.strip())
        if not sep or not platform.strip() or not addresses:
            raise GatewayError(f"--platform {item!r}: expected PLATFORM=URL[,URL…] (host:1099/JADE=http://…)")
        for address in addresses:
            try:
                check_address(address)
            except MTPError as exc:
                raise GatewayError(f"--platform {platform.strip()}: {exc}") from None
        platforms[platform.strip()] = addresses
    return platforms


def _external_spec(config: GatewayConfig) -> SystemSpec:
    """The specification of ``config``; GatewayError when it does not load or has no external
    role."""
    try:
        spec = load(config.spec)
    except SpecError as exc:
        raise GatewayError(str(exc)) from None
    if not spec.externals:
        raise GatewayError(f"{config.spec}: no external role ([[externals]]): nobody may come in")
    return spec


def _transport(config: GatewayConfig) -> ZenohTransport:
    """The gateway's session with ``config``'s router; GatewayError when there are no
    credentials for it or the router does not answer (or refuses them)."""
    try:
        return ZenohTransport([config.endpoint], wait_for_router=False, identity=GATEWAY)
    except ValueError as exc:  # CredentialError: no credentials for the gateway in the folder
        raise GatewayError(str(exc)) from None
    except Exception:  # zenoh.ZError
        why = refusal(config.endpoint, GATEWAY, security_for([config.endpoint]))
        raise GatewayError(why) from None


def serve(
    config: GatewayConfig, stop: threading.Event, ready: threading.Event | None = None
) -> dict[str, int]:
    """Run the gateway until ``stop`` is set; set ``ready`` once it serves. Returns its
    counters. Raises GatewayError when the specification does not load or has no external
    role, when the port is in use or cannot be bound (checked before the fleet is reached), or
    when no router answers (or it refuses the gateway's credentials)."""
    spec = _external_spec(config)
    address = config.address or f"http://{config.host}:{config.port}/acc"
    platforms = parse_platforms(config.platforms)
    try:
        max_poll_us()  # a malformed ROCO_RECEIVE_POLL_US is named as such, not as a missing router
    except ValueError as exc:
        raise GatewayError(str(exc)) from None
    if listening(f"tcp/{config.host}:{config.port}"):
        raise GatewayError(port_in_use(config.host, config.port, "--port"))
    transport = _transport(config)
    try:
        gateway, server = open_gateway(
            transport, spec, config.host, config.port, address, routers=[config.endpoint], platforms=platforms
        )
    except OSError as exc:
        transport.close()
        where, why = f"{config.host}:{config.port}", exc.strerror or str(exc)
        raise GatewayError(f"cannot listen on {where} ({why}): choose another --port") from None
    routes = ", ".join(f"{role} → {agent} on {channel}" for channel, role, agent in gateway.routes)
    print(f"roco gateway: {address} ↔ {config.endpoint} ({routes})", flush=True)
    if ready is not None:
        ready.set()
    try:
        while not stop.wait(0.5):  # a timeout: a signal taken by a Zenoh thread must still end it
            pass
    finally:
        server.stop()
        gateway.stop()
        transport.close()
    return dict(gateway.counters)


def main(config: GatewayConfig) -> int:
    """Run ``roco gateway`` in this process until SIGINT or SIGTERM; 0 when it ran, 1 (one line
    on stderr) when it could not start."""

    def shown(counters: Counters) -> str:
        return ", ".join(f"{k} {v}" for k, v in sorted(counters.items())) or "nothing"

    return run_until_stopped("gateway", lambda stop: serve(config, stop), (GatewayError,), shown)
