"""Where the gateway may post an answer: ``http://`` addresses that are not roco's own.

roco's own addresses are the gateway's (the URL it tells foreign platforms, the host and port
it listens on) and the fleet's routers' endpoints: posting there would make the gateway read
its own answers (a loop) or write HTTP into a router. An address is roco's when its port is
one of those and its host is the same, or both hosts are this machine (a loopback or
unspecified address, ``localhost``, this machine's name or one of its addresses). A name
that only resolves to this machine is caught when the posting client resolves it
(services/gateway/poster.py).
"""

from __future__ import annotations

import contextlib
import ipaddress
import socket
from collections.abc import Iterable
from dataclasses import dataclass, field
from urllib.parse import urlsplit

from services.gateway.bounds import DEFAULT_LIMITS, Limits

__all__ = ["Destinations", "Usable", "endpoint_of", "this_machine"]


def this_machine() -> frozenset[str]:
    """Names and addresses of this machine, lower case: ``localhost``, its host name and the
    addresses that name resolves to (from /etc/hosts or DNS; none when that fails)."""
    names = {"localhost", "ip6-localhost", "localhost.localdomain"}
    host = socket.gethostname().lower()
    names.add(host)
    with contextlib.suppress(OSError):
        names.update(str(info[4][0]).lower() for info in socket.getaddrinfo(host, None))
    return frozenset(names)


def _is_local(host: str, machine: frozenset[str]) -> bool:
    host = host.strip("[]").lower()
    if host in machine:
        return True
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return False
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback or ip.is_unspecified


def endpoint_of(address: str) -> tuple[str, int] | None:
    """(host, port) of a URL (``http://h:p/…``, default port 80) or a Zenoh endpoint
    (``tcp/h:p``); None when it names none."""
    if "://" not in address and "/" in address:  # a Zenoh endpoint: proto/host:port
        address = "zenoh://" + address.split("/", 1)[1]
    try:
        url = urlsplit(address)
        port = url.port
    except ValueError:
        return None
    if not url.hostname:
        return None
    return url.hostname.lower(), port or 80


@dataclass(frozen=True)
class Usable:
    """The addresses an answer is tried at (``addresses``, in order) and why the others given
    are not (``skipped``: reason → count; reasons ``roco_address``, ``not_http``, ``too_long``,
    ``over_cap``)."""

    addresses: tuple[str, ...]
    skipped: dict[str, int] = field(default_factory=dict)


class Destinations:
    """Where answers may go (module docstring): not to ``own`` (host, port) endpoints of
    roco's, at most ``limits.max_answer_addresses`` addresses of at most
    ``limits.max_address`` characters each."""

    def __init__(
        self,
        own: Iterable[tuple[str, int]],
        limits: Limits = DEFAULT_LIMITS,
        machine: frozenset[str] | None = None,
    ) -> None:
        self.own = frozenset((h.strip("[]").lower(), p) for h, p in own)
        self.limits = limits
        self.machine = this_machine() if machine is None else machine

    @classmethod
    def of(
        cls,
        address: str,
        listen: tuple[str, int] | None = None,
        routers: Iterable[str] = (),
        limits: Limits = DEFAULT_LIMITS,
    ) -> Destinations:
        """The destinations of a gateway posted to at ``address``, listening on ``listen``
        (host, port; None: the address's), on a fleet whose routers are ``routers`` (Zenoh
        endpoints)."""
        own = [e for e in (endpoint_of(a) for a in (address, *routers)) if e is not None]
        return cls([*own, *([listen] if listen else [])], limits)

    def is_roco(self, host: str, port: int) -> bool:
        """Whether ``host``:``port`` is one of roco's endpoints (module docstring)."""
        host = host.strip("[]").lower()
        local = _is_local(host, self.machine)
        return any(port == p and (host == h or (local and _is_local(h, self.machine))) for h, p in self.own)

    def usable(self, addresses: Iterable[str]) -> Usable:
        """The addresses of ``addresses`` an answer may be posted to, in order, and why the
        others are not (:class:`Usable`)."""
        kept: list[str] = []
        skipped: dict[str, int] = {}

        def skip(reason: str) -> None:
            skipped[reason] = skipped.get(reason, 0) + 1

        for address in addresses:
            if len(kept) == self.limits.max_answer_addresses:
                skip("over_cap")
                continue
            if len(address) > self.limits.max_address:
                skip("too_long")
                continue
            endpoint = endpoint_of(address) if address.lower().startswith("http://") else None
            if endpoint is None:
                skip("not_http")
            elif self.is_roco(*endpoint):
                skip("roco_address")
            else:
                kept.append(address)
        return Usable(tuple(kept), skipped)
