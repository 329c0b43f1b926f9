"""Credentials of a deployment: a private certificate authority, one certificate per identity
(common name = the identity: an agent's name, ``recorder``, ``operator``) and the router's, and a
user/password dictionary for Zenoh's ``usrpwd`` authentication.

Layout of a credentials folder (:func:`issue`; every key and password file mode 0600, each file
written whole and fsynced, services/security/files.py)::

    ca.pem  ca.key             the private CA (keep ca.key off the robot: it issues identities)
    router.pem  router.key     the router's TLS certificate (SAN: localhost, 127.0.0.1, router)
    passwords.txt              the router's usrpwd dictionary, ``user:password`` per line
    acl.json                   the router's access control (services/deploy/deploy.py)
    <id>/cert.pem <id>/key.pem <id>/password
                               what identity ``<id>`` needs to connect (and nothing else)

Keys are ECDSA P-256 (issuing a whole deployment takes ~50 ms), certificates X.509 v3 signed with
SHA-256, valid ``days`` days (default 365). Zenoh 1.10 checks no revocation list: an identity is
revoked by taking it out of the router's ACL and password dictionary (:func:`revoke`) and
restarting the router, or, for TLS alone, by issuing a new CA (docs/security.md).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import secrets
from collections.abc import Iterable
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from services.security.files import write_file
from services.security.folder import (
    ACL_FILE,
    CA_CERT,
    CA_KEY,
    CERT,
    KEY,
    PASSWORD,
    PASSWORDS,
    ROUTER,
    ROUTER_IPS,
    ROUTER_NAMES,
    CredentialError,
    Identity,
    identities,
    identity,
    read_passwords,
)

__all__ = [
    "ACL_FILE",
    "CA_CERT",
    "CA_KEY",
    "CERT",
    "KEY",
    "PASSWORD",
    "PASSWORDS",
    "ROUTER",
    "ROUTER_IPS",
    "ROUTER_NAMES",
    "CredentialError",
    "Identity",
    "identities",
    "identity",
    "issue",
    "issue_identity",
    "issue_router",
    "issue_router_identity",
    "make_ca",
    "read_passwords",
    "revoke",
]


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )


def _name(common_name: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "roco"),
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
        ]
    )


def _issue_cert(
    common_name: str,
    ca_key: ec.EllipticCurvePrivateKey,
    ca_name: x509.Name,
    days: int,
    *,
    server: bool,
    sans: list[x509.GeneralName] | None = None,
) -> tuple[ec.EllipticCurvePrivateKey, x509.Certificate]:
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(ca_name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=True,
                key_cert_sign=False,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
                if server
                else [ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
    )
    if sans is None:
        sans = [x509.DNSName(common_name)]
        if server:
            sans = _router_sans(ROUTER_NAMES, ROUTER_IPS)
    builder = builder.add_extension(x509.SubjectAlternativeName(sans), critical=False)
    return key, builder.sign(ca_key, hashes.SHA256())


def _router_sans(names: Iterable[str], ips: Iterable[str]) -> list[x509.GeneralName]:
    return [x509.DNSName(n) for n in names] + [x509.IPAddress(ipaddress.ip_address(ip)) for ip in ips]


def _load_ca(out: Path) -> tuple[ec.EllipticCurvePrivateKey, x509.Certificate]:
    try:
        key = serialization.load_pem_private_key((out / CA_KEY).read_bytes(), password=None)
        cert = x509.load_pem_x509_certificate((out / CA_CERT).read_bytes())
    except OSError as exc:
        raise CredentialError(f"{out}: no CA ({exc})") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise CredentialError(f"{out / CA_KEY}: not an EC private key")
    return key, cert


def make_ca(out: Path, days: int = 3650) -> None:
    """Create a private CA in ``out`` (``ca.pem``, ``ca.key``), replacing any there (which
    revokes every certificate it issued)."""
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    name = _name("roco deployment CA")
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    write_file(out / CA_KEY, _key_pem(key), secret=True)
    write_file(out / CA_CERT, cert.public_bytes(serialization.Encoding.PEM))


def issue_identity(out: Path, name: str, days: int = 365) -> Identity:
    """Issue (or re-issue) identity ``name`` with the CA in ``out``: a certificate with common
    name ``name``, a key and a fresh random password, entered in ``passwords.txt``. The
    certificate serves as well as connects, for ``localhost`` and ``127.0.0.1``: an agent's
    session listens for its peers' direct links on loopback (services/runtime/transport.py,
    one hop) and they check its name there. Raises
    CredentialError when ``out`` has no CA or ``name`` is not a plain name."""
    if not name or not all(c.isalnum() or c in "_-" for c in name) or name == ROUTER:
        raise CredentialError(f"not an identity name: {name!r}")
    ca_key, ca_cert = _load_ca(out)
    sans = [x509.DNSName(name), *_router_sans(("localhost",), ROUTER_IPS)]
    key, cert = _issue_cert(name, ca_key, ca_cert.subject, days, server=True, sans=sans)
    return _store_identity(out, name, key, cert)


def _store_identity(
    out: Path, name: str, key: ec.EllipticCurvePrivateKey, cert: x509.Certificate
) -> Identity:
    """Write identity ``name``'s key, certificate and a fresh password into ``out/<name>/`` and
    enter the password in ``passwords.txt``."""
    write_file(out / name / KEY, _key_pem(key), secret=True)
    write_file(out / name / CERT, cert.public_bytes(serialization.Encoding.PEM))
    password = secrets.token_urlsafe(24)
    write_file(out / name / PASSWORD, password.encode(), secret=True)
    users = {u: p for u, p in read_passwords(out).items() if u != name}
    users[name] = password
    _write_passwords(out, users)
    return identity(out, name)


def issue_router_identity(
    out: Path, name: str, names: Iterable[str] = (), ips: Iterable[str] = (), days: int = 365
) -> Identity:
    """Issue (or re-issue) the identity of one router of a mesh (``router_<host>``, e.g.
    ``router_robot``) with the CA in ``out``: like :func:`issue_identity` (folder ``<name>/``, a
    password in ``passwords.txt``: it authenticates to the routers it connects to), but its
    certificate serves as well as connects and names the host: the SANs of the single router's
    certificate (``localhost``, ``router``, ``127.0.0.1``: its own host's clients and the
    compose service) and ``names`` and ``ips`` (the addresses the other routers reach it at; a
    router connecting to an address its certificate does not name is refused by Zenoh's name
    check). Raises
    CredentialError when ``out`` has no CA or ``name`` does not start with ``router_``."""
    if not name.startswith(ROUTER + "_") or not all(c.isalnum() or c in "_-" for c in name):
        raise CredentialError(f"not a router identity name (router_<host>): {name!r}")
    ca_key, ca_cert = _load_ca(out)
    sans = _router_sans(dict.fromkeys([*ROUTER_NAMES, *names]), dict.fromkeys([*ROUTER_IPS, *ips]))
    key, cert = _issue_cert(name, ca_key, ca_cert.subject, days, server=True, sans=sans)
    return _store_identity(out, name, key, cert)


def issue_router(out: Path, days: int = 365) -> None:
    """Issue the router's TLS certificate (``router.pem``, ``router.key``) with the CA in ``out``."""
    ca_key, ca_cert = _load_ca(out)
    key, cert = _issue_cert(ROUTER, ca_key, ca_cert.subject, days, server=True)
    write_file(out / f"{ROUTER}.key", _key_pem(key), secret=True)
    write_file(out / f"{ROUTER}.pem", cert.public_bytes(serialization.Encoding.PEM))


def issue(out: Path, names: Iterable[str], days: int = 365) -> list[Identity]:
    """A whole deployment's credentials in ``out``: a new CA, the router's certificate and one
    identity per name (see the module docstring for the layout)."""
    out.mkdir(parents=True, exist_ok=True)
    make_ca(out)
    issue_router(out, days)
    (out / PASSWORDS).unlink(missing_ok=True)
    return [issue_identity(out, n, days) for n in names]


def _write_passwords(out: Path, users: dict[str, str]) -> None:
    write_file(out / PASSWORDS, "".join(f"{u}:{p}\n" for u, p in sorted(users.items())).encode(), secret=True)


def revoke(out: Path, name: str) -> bool:
    """Take identity ``name`` out of the password dictionary and delete its folder; True when it
    was there. Its certificate stays valid for TLS until the CA is replaced: the router's ACL
    (generated without ``name``) is what then refuses it (docs/security.md)."""
    users = read_passwords(out)
    found = users.pop(name, None) is not None
    _write_passwords(out, users)
    folder = out / name
    if folder.is_dir():
        found = True
        for f in folder.iterdir():
            f.unlink()
        folder.rmdir()
    return found
