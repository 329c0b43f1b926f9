"""``roco deploy``: a deployment's credentials folder, one identity issued again and one revoked
(services/deploy/cli.py, deploy.py, certs.py)."""

from __future__ import annotations

import json
import stat
from pathlib import Path

from cryptography import x509
from cryptography.x509.oid import NameOID
from typer.testing import CliRunner

from services.cli import app
from services.security import certs

runner = CliRunner()


def test_certs_issue_revoke(tmp_path: Path) -> None:
    out = tmp_path / "certs"
    r = runner.invoke(app, ["deploy", "certs", str(out)])
    assert r.exit_code == 0, r.output
    names = certs.identities(out)
    assert names == sorted(
        ["a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex", "recorder", "operator", "gateway"]
    )
    ca = x509.load_pem_x509_certificate((out / certs.CA_CERT).read_bytes())
    for n in names:
        cert = x509.load_pem_x509_certificate((out / n / certs.CERT).read_bytes())
        assert cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == n
        assert cert.issuer == ca.subject
        assert stat.S_IMODE((out / n / certs.KEY).stat().st_mode) == 0o600
    router = x509.load_pem_x509_certificate((out / "router.pem").read_bytes())
    san = router.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert {"localhost", "router"} <= set(san.get_values_for_type(x509.DNSName))
    acl = json.loads((out / certs.ACL_FILE).read_text())
    assert acl["default_permission"] == "deny"
    assert all(s["cert_common_names"] == [s["id"]] for s in acl["subjects"])
    assert set(certs.read_passwords(out)) == set(names)

    kept = (out / certs.CA_CERT).read_bytes()
    assert runner.invoke(app, ["deploy", "certs", str(out), "--keep"]).exit_code == 0
    assert (out / certs.CA_CERT).read_bytes() == kept

    old = (out / "a_pl" / certs.PASSWORD).read_text()
    assert runner.invoke(app, ["deploy", "issue", str(out), "a_pl"]).exit_code == 0
    assert (out / "a_pl" / certs.PASSWORD).read_text() != old
    assert runner.invoke(app, ["deploy", "issue", str(out), "mallory"]).exit_code == 2

    assert runner.invoke(app, ["deploy", "revoke", str(out), "a_pl"]).exit_code == 0
    assert "a_pl" not in certs.read_passwords(out) and not (out / "a_pl").exists()
    acl = json.loads((out / certs.ACL_FILE).read_text())
    assert "a_pl" not in {s["id"] for s in acl["subjects"]}
    assert all(not r["id"].startswith("a_pl/") for r in acl["rules"])
    assert runner.invoke(app, ["deploy", "revoke", str(out), "a_pl"]).exit_code == 2


def test_acl_and_table_print() -> None:
    r = runner.invoke(app, ["deploy", "acl", "--no-tls"])
    assert r.exit_code == 0
    assert json.loads(r.output)["default_permission"] == "deny"
    r = runner.invoke(app, ["deploy", "table"])
    assert "| a_pl | C3 → a_co, C4 → a_km |" in r.output
