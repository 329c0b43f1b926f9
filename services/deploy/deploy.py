"""A deployment's credentials and access control in one folder (docs/security.md).

:func:`prepare` issues everything a fleet needs (services/security/certs.py) for the identities
of the specification (services/spec_check/acl.py) and writes the router's ``acl.json``;
:func:`revoke_identity` takes one identity out (password, credentials, ACL subject).
"""

from __future__ import annotations

import json
from pathlib import Path

from services.security import certs
from services.security.files import write_file
from services.spec.model import SystemSpec
from services.spec_check.acl import ROUTER_PREFIX, acl_config, identities, with_routers


def write_acl(out: Path, spec: SystemSpec, *, tls: bool) -> None:
    """Write ``out/acl.json`` for the identities issued in ``out``; ``tls``: subjects are
    matched by certificate common name as well as user name."""
    issued = certs.identities(out)
    acl = with_routers(
        acl_config(spec, tls=tls, only=set(issued)), [n for n in issued if n.startswith(ROUTER_PREFIX)]
    )
    write_file(out / certs.ACL_FILE, json.dumps(acl, indent=1).encode())


def acl_uses_tls(out: Path) -> bool:
    """Whether ``out/acl.json`` matches subjects by certificate common name."""
    try:
        acl = json.loads((out / certs.ACL_FILE).read_text())
    except (OSError, ValueError):
        return False
    return any("cert_common_names" in s for s in acl.get("subjects", []))


def prepare(out: Path, spec: SystemSpec, *, tls: bool, days: int = 365) -> list[str]:
    """Issue a new CA, the router's certificate, every identity of ``spec`` and the ACL into
    ``out`` (replacing what was there); returns the identities."""
    names = identities(spec)
    certs.issue(out, names, days)
    write_acl(out, spec, tls=tls)
    return names


def ensure(out: Path, spec: SystemSpec, *, tls: bool) -> Path:
    """``out`` prepared for ``spec``: reused when it already holds an ACL (a service of a running
    fleet started again must keep the router's credentials), else :func:`prepare`\\ d."""
    if not (out / certs.ACL_FILE).is_file():
        prepare(out, spec, tls=tls)
    return out


def missing(out: Path, spec: SystemSpec) -> list[str]:
    """The identities of ``spec`` (its agents', the recorder's, the operator's, …) that the
    credentials folder ``out`` holds none of, in the specification's order."""
    held = set(certs.identities(out))
    return [name for name in identities(spec) if name not in held]


def kept_line(out: Path, spec: SystemSpec) -> str:
    """What ``roco deploy certs --keep`` says of the folder ``out`` it keeps: the identities it
    holds and those of ``spec`` it lacks (revoked, or the folder is another system's), which
    are not issued: a revoked identity stays revoked."""
    line = f"kept the credentials in {out} ({', '.join(certs.identities(out))})"
    if lacking := missing(out, spec):
        line += (
            f"; none for {', '.join(lacking)} of the specification, whose services cannot connect "
            f"(revoked, or the folder is another system's: `roco deploy issue {out} NAME`, or "
            f"`roco deploy certs {out}` without --keep for a new deployment)"
        )
    return line


def issue_identity(out: Path, spec: SystemSpec, name: str, days: int = 365) -> certs.Identity:
    """(Re-)issue one identity of ``spec`` in ``out`` and rewrite the ACL. Raises
    CredentialError when ``spec`` has no such identity or ``out`` no CA."""
    if name not in identities(spec):
        raise certs.CredentialError(f"{name!r} is not an identity of the specification")
    ident = certs.issue_identity(out, name, days)
    write_acl(out, spec, tls=acl_uses_tls(out))
    return ident


def issue_router(
    out: Path, spec: SystemSpec, name: str, names: list[str], ips: list[str], days: int = 365
) -> certs.Identity:
    """(Re-)issue meshed router ``name`` (``router_<host>``) reachable at ``names``/``ips`` in
    ``out`` and rewrite the ACL so that the routers trust one another (docs/deploy.md)."""
    ident = certs.issue_router_identity(out, name, names, ips, days)
    write_acl(out, spec, tls=acl_uses_tls(out))
    return ident


def revoke_identity(out: Path, spec: SystemSpec, name: str) -> bool:
    """Take ``name`` out of ``out``: password, credentials and ACL subject (the router refuses it
    once restarted with the new files). True when it was there."""
    found = certs.revoke(out, name)
    write_acl(out, spec, tls=acl_uses_tls(out))
    return found
