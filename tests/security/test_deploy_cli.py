"""``roco deploy``: a deployment's credentials folder, one identity issued again and one revoked
(services/cli/deploy.py, services/deploy/deploy.py, services/security/certs.py)."""

from __future__ import annotations

import json
import stat
from pathlib import Path

from cryptography import x509
from cryptography.x509.oid import NameOID
from typer.testing import CliRunner

from services.cli import app
from services.security import certs
from services.spec.model import default_spec

runner = CliRunner()


def test_certs_issue_revoke(tmp_path: Path) -> None:
    out = tmp_path / "certs"
    r = runner.invoke(app, ["deploy", "certs", str(out)])
    assert r.exit_code == 0, r.output
    names = certs.identities(out)
    # one identity per agent of the specification, and the fleet's own
    assert names == sorted(
        [*default_spec().agent_names, "recorder", "operator", "gateway", "ros2", "ros2_peer"]
    )
    assert {"a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex"} <= set(names)
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


def test_a_meshed_routers_identity_names_its_addresses_and_the_routers_trust_each_other(
    tmp_path: Path,
) -> None:
    """``roco deploy router``: a certificate of the CA that serves and connects with
    the router's addresses as SANs, a password, and one ACL subject for the routers matched by
    certificate common name only; a bad name or address is one line, exit 2."""
    out = tmp_path / "certs"
    assert runner.invoke(app, ["deploy", "certs", str(out)]).exit_code == 0
    r = runner.invoke(
        app, ["deploy", "router", str(out), "router_robot", "--ip", "10.1.2.3", "--dns", "robot.lan"]
    )
    assert r.exit_code == 0, r.output
    cert = x509.load_pem_x509_certificate((out / "router_robot" / certs.CERT).read_bytes())
    sans = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert {"localhost", "robot.lan"} <= set(sans.get_values_for_type(x509.DNSName))
    assert {str(a) for a in sans.get_values_for_type(x509.IPAddress)} == {"127.0.0.1", "10.1.2.3"}
    usage = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    assert {u.dotted_string for u in usage} == {"1.3.6.1.5.5.7.3.1", "1.3.6.1.5.5.7.3.2"}  # server, client
    assert "router_robot" in certs.read_passwords(out)
    acl = json.loads((out / certs.ACL_FILE).read_text())
    routers = [s for s in acl["subjects"] if s["id"] == "routers"]
    assert routers == [{"id": "routers", "cert_common_names": ["router_robot"]}]
    rule = next(x for x in acl["rules"] if x["id"] == "routers")
    # every key, and zenoh-ext's verbatim @adv chunks (caches, tokens), which ** does not match
    assert rule["key_exprs"] == ["**", "**/@adv/**"] and set(rule["flows"]) == {"ingress", "egress"}
    for bad in (["robot"], ["router_x", "--ip", "not-an-address"]):
        r = runner.invoke(app, ["deploy", "router", str(out), *bad])
        assert r.exit_code == 2 and r.output.startswith("roco: "), r.output


def test_certs_into_a_folder_it_cannot_write_is_one_line(tmp_path: Path) -> None:
    """As the compose ``certs`` service meets a ROCO_CERTS that is not its user's: no traceback.
    (A path under a file stands for the folder: root may write any folder.)"""
    blocked = tmp_path / "file"
    blocked.write_text("")
    r = runner.invoke(app, ["deploy", "certs", str(blocked / "certs"), "--keep"])
    assert r.exit_code == 1, r.output
    assert r.output.startswith(f"roco: cannot write the credentials in {blocked / 'certs'}: Not a directory")
    assert "docs/deploy.md" in r.output
