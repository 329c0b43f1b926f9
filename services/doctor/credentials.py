"""The credentials of the fleet ``roco up`` left under ``runs/`` (``runs/.fleet.json``): the
operator's identity, which ``roco send``/``status``/``fault`` connect with, and the validity
of its certificate and the CA's."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

from cryptography import x509

from services.doctor.model import Check, Use
from services.fleet_state import FLEET_FILE
from services.security.certs import CA_CERT, CredentialError, identity

OPERATOR = "operator"  # services/security/context.py OPERATOR


def _valid_until(pem: Path) -> dt.datetime:
    """The certificate's end of validity (UTC). Raises OSError or ValueError when unreadable."""
    return x509.load_pem_x509_certificate(pem.read_bytes()).not_valid_after_utc


def checks(runs_dir: Path, now: dt.datetime | None = None) -> list[Check]:
    """One check: no fleet is up (informative), a fleet without access control
    (informative), or its operator identity readable with the CA's and its certificate valid
    at ``now`` (default: the current time)."""
    state = runs_dir / FLEET_FILE
    if not state.is_file():
        return [
            Check("fleet credentials", Use.FLEET, False, f"no fleet is up (no {state})", informative=True)
        ]
    try:
        run_dir = Path(json.loads(state.read_text())["run_dir"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return [Check("fleet credentials", Use.FLEET, False, f"{state}: unreadable ({exc})", "roco down")]
    folder = run_dir / "security"
    if not folder.is_dir():
        return [
            Check(
                "fleet credentials",
                Use.FLEET,
                False,
                f"the fleet in {run_dir} runs without access control",
                informative=True,
            )
        ]
    return [_operator_check(folder, now)]


def _operator_check(folder: Path, now: dt.datetime | None) -> Check:
    """The operator identity of a fleet with access control: readable with the CA's, and its
    certificate valid at ``now`` (default: the current time)."""
    try:
        ident = identity(folder, OPERATOR)
        missing = [p.name for p in (ident.cert, ident.key, folder / CA_CERT) if not p.is_file()]
        if missing:
            raise CredentialError(f"{folder}: {OPERATOR} lacks {', '.join(missing)}")
        until = min(_valid_until(ident.cert), _valid_until(folder / CA_CERT))
    except (CredentialError, OSError, ValueError) as exc:
        how = f"roco deploy issue {folder} {OPERATOR}"
        return Check("fleet credentials", Use.FLEET, False, str(exc), how)
    now = now or dt.datetime.now(dt.UTC)
    ok = now < until
    detail = f"{OPERATOR} of {folder}, valid until {until:%Y-%m-%d}"
    return Check(
        "fleet credentials",
        Use.FLEET,
        ok,
        detail if ok else f"{OPERATOR} of {folder} expired on {until:%Y-%m-%d}",
        "" if ok else f"roco deploy issue {folder} {OPERATOR} (then restart the fleet)",
    )
