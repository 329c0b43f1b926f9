"""A credentials folder's layout (services/security/certs.py issues it) and what a client reads
from it to connect: its :class:`Identity` and the router's password dictionary.

A client reads ``ca.pem`` and its own ``<id>/`` (:func:`identity`), all that a container of
deploy/compose.yaml mounts (services/deploy/compose.py); a one-hop peer of a local fleet also
reads ``acl.json`` and ``passwords.txt`` (services/runtime/zenoh_config.py ``one_hop``).

Kept apart from issuing (certs.py, which needs the ``cryptography`` package: ≈ 11 MiB resident
with OpenSSL) so that every agent, the recorder and the router, which only read the folder,
do not load it (lean processes).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
ROUTER = "router"
PASSWORDS = "passwords.txt"
ACL_FILE = "acl.json"
"""The router's ``access_control`` section (services/deploy/deploy.py writes it)."""
CERT = "cert.pem"
KEY = "key.pem"
PASSWORD = "password"
ROUTER_NAMES = ("localhost", "router")
"""DNS names in the router's certificate: the local host and the compose service name."""
ROUTER_IPS = ("127.0.0.1",)


class CredentialError(ValueError):
    """A credentials folder that is missing a file, or an identity it does not hold."""


@dataclass(frozen=True)
class Identity:
    """What one client needs to connect: ``name`` (user name and certificate common name),
    ``password``, and the paths of its certificate, key and the CA certificate."""

    name: str
    password: str
    cert: Path
    key: Path
    ca: Path


def read_passwords(out: Path) -> dict[str, str]:
    """The usrpwd dictionary of ``out`` (empty when there is none)."""
    try:
        text = (out / PASSWORDS).read_text()
    except FileNotFoundError:
        return {}
    users: dict[str, str] = {}
    for line in text.splitlines():
        user, sep, password = line.partition(":")
        if sep:
            users[user] = password
    return users


def identity(out: Path, name: str) -> Identity:
    """Identity ``name`` of the credentials folder ``out``. Raises CredentialError when its
    password file is missing."""
    try:
        password = (out / name / PASSWORD).read_text().strip()
    except OSError as exc:
        raise CredentialError(f"{out}: no credentials for {name!r} ({exc})") from None
    return Identity(name, password, out / name / CERT, out / name / KEY, out / CA_CERT)


def identities(out: Path) -> list[str]:
    """The identities issued in ``out`` (its sub-folders holding a password)."""
    return sorted(p.parent.name for p in out.glob(f"*/{PASSWORD}"))
