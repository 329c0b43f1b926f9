"""Refusals seen, and operators' credentials.

A router process with access control (user/password over TCP on a free loopback port, spawned
by the launcher, ended by PID) refuses what an agent puts outside its channels or as another;
the router counts and names each one (identity, message, key, time) in ``refusals.jsonl`` of
its run folder and in ``roco status``. The operator's tools reach it with ``--credentials`` or
``ROCO_SECURITY`` and, without them, say in one line that the router refused the session for
want of credentials. Waits are on queues or on a condition polled with a deadline.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.refusals import (
    UNKNOWN,
    RefusalLog,
    RefusalReport,
    collect_reports,
    read_refusals,
    summary,
)
from services.runtime.session import open_client
from services.security import certs
from services.security.context import register
from tests.security.test_access_control import Inbox, routed

WAIT_S = 15.0

# Lines of eclipse-zenoh 1.10.2's log as the router wrote them (ANSI colours included)
ACL = "\x1b[2mzenoh::net::routing::interceptor::access_control\x1b[0m\x1b[2m:\x1b[0m"
ZID = "460cf667c9ac31853f05d8a9322fdf0d"
SUBJECT = f"{ZID} on Interface(lo)+Username(a_pl)+Transport(Tcp)+{ZID}"


def line(t: str, text: str, thread: int = 8) -> str:
    return (
        f"\x1b[2m2026-11-22T22:01:{t}Z\x1b[0m \x1b[35mTRACE\x1b[0m rx-0 ThreadId({thread:02d}) {ACL} {text}\n"
    )


def test_the_log_of_zenohs_acl_gives_each_refusal_named() -> None:
    log = RefusalLog()
    lines = [
        # a declared key: its decisions are computed ahead (9 kinds), none is a refusal
        line("09.000000", "ACL (ingress): caching permissions for `roco/fipa/C6/a_pl/a_km` ..."),
        *[
            line("09.000001", f"{SUBJECT} is unauthorized to {kind} (ingress) on roco/fipa/C6/a_pl/a_km")
            for kind in (
                "Query",
                "Reply",
                "Put",
                "Delete",
                "Declare/Undeclare Subscriber",
                "Declare/Undeclare Queryable",
                "Declare/Undeclare Liveliness Token",
                "Liveliness Query",
                "Declare Liveliness Subscriber",
            )
        ],
        # a put on a key not declared: decided per message, subject named
        line("09.924796", f"{SUBJECT} is unauthorized to Put (ingress) on roco/fipa/C1/a_pl/a_ta"),
        line("09.924800", f"{SUBJECT} is authorized to Put (ingress) on roco/fipa/C4/a_pl/a_km"),
        # puts through the declared publisher: the cached decision names only the session
        line(
            "10.100000",
            f"Using cached result: {ZID} is unauthorized to Put (ingress) on roco/fipa/C6/a_pl/a_km",
        ),
        line(
            "10.200000",
            f"Using cached result: {ZID} is unauthorized to Put (ingress) on roco/fipa/C6/a_pl/a_km",
        ),
        line("10.300000", "Using cached result: 99 is unauthorized to Put (ingress) on roco/x", thread=9),
        "2026-11-22T22:01:11Z  INFO zenoh::net::routing::interceptor::low_pass: unrelated\n",
        # a session refused at authentication, its peer from the accepting thread's last line
        "2026-11-22T22:32:23.565313Z DEBUG acc-0 ThreadId(05) zenoh_link_tls::unicast: Accepted TLS "
        "connection on 127.0.0.1:34301: 127.0.0.1:59584. Common Name: a_pl.\n",
        "2026-11-22T22:32:23.566030Z DEBUG acc-0 ThreadId(05) zenoh_transport::unicast::establishment::"
        "accept: UsrPwd extension - Recv OpenSyn. Invalid password. at /root/.cargo/…/usrpwd.rs:424.\n",
        "2026-11-22T22:32:23.262709Z  WARN acc-0 ThreadId(05) zenoh_link_tls::unicast: invalid peer "
        "certificate: BadSignature. Hint: increase the system open file limit.\n",
    ]
    refused = [r for r in map(log.feed, lines) if r is not None]
    assert [(r.identity, r.message, r.flow, r.key) for r in refused] == [
        ("a_pl", "put", "ingress", "roco/fipa/C1/a_pl/a_ta"),
        ("a_pl", "put", "ingress", "roco/fipa/C6/a_pl/a_km"),
        ("a_pl", "put", "ingress", "roco/fipa/C6/a_pl/a_km"),
        (UNKNOWN, "put", "ingress", "roco/x"),
        ("a_pl", "authenticate", "ingress", "wrong password"),
        (UNKNOWN, "authenticate", "ingress", "bad certificate: BadSignature"),
    ]
    assert refused[4].peer == "tls/127.0.0.1:59584" and refused[5].peer == ""
    assert refused[0].t == pytest.approx(1795384869.924796)  # 2026-11-22T22:01:09.924796Z
    report = log.report("router-zid", 0.0)
    assert report.counters["refused"] == 6 and report.counters["refused.put"] == 4
    first = report.named[0]
    assert (first.identity, first.key, first.count) == ("a_pl", "roco/fipa/C6/a_pl/a_km", 2)
    assert first.last - first.first == pytest.approx(0.1, abs=1e-5)
    text = summary(report)
    assert text.startswith("refused 6: a_pl put roco/fipa/C6/a_pl/a_km ×2 (last ")
    assert text.endswith("; withheld 0")


@pytest.fixture(scope="module")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    run_dir = tmp_path_factory.mktemp("refusals")
    (run_dir / "logs").mkdir()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=False)
    fleet.start_router()
    yield fleet
    fleet.stop()
    register(fleet.endpoint, None)


def router_report(session: zenoh.Session, until: int) -> RefusalReport:
    """The router's report once it counted ``until`` refusals sent by clients (it reads Zenoh's
    log on a thread of its own: a refusal is counted shortly after it was made)."""
    deadline = time.monotonic() + WAIT_S
    while True:
        got: list[RefusalReport] = []
        with collect_reports(session, got):
            session.put(keys.COUNTERS_ASK, b"")
        if got and got[0].counters.get("refused.ingress", 0) >= until:
            return got[0]
        if time.monotonic() > deadline:
            pytest.fail(f"the router counted {got[0].counters if got else 'nothing'}, not {until} refusals")


def cli(args: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    environ = {
        k: v for k, v in os.environ.items() if k not in ("ROCO_SECURITY", "ROCO_IDENTITY", "ROCO_ROUTER")
    }
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
        env=environ | env,
    )


def test_a_planted_spoof_is_refused_counted_and_named(router: Fleet, tmp_path: Path) -> None:
    ep = router.endpoint
    recorder = open_client(ep, identity="recorder")
    pl = open_client(ep, identity="a_pl")
    operator = open_client(ep)
    try:
        seen = Inbox()
        recorder.declare_subscriber(keys.FIPA_ALL, seen)
        allowed = keys.fipa_key("C4", "a_pl", "a_km")
        routed(pl, allowed, seen)
        spoof = keys.fipa_key("C1", "a_co", "a_ta")  # a_pl posing as a_co to a_ta
        foreign = keys.fipa_key("C1", "a_pl", "a_ta")  # a channel a_pl does not own
        before = router_report(operator, 0).counters.get("refused.ingress", 0)
        for _ in range(3):
            pl.put(spoof, b"forged")
        publisher = pl.declare_publisher(foreign)  # its decision is cached by the router
        for _ in range(2):
            publisher.put(b"forged")
        routed(pl, allowed, seen)  # after the forged ones, on the same session
        assert spoof not in seen.keys and foreign not in seen.keys
        report = router_report(operator, before + 5)
    finally:
        for s in (pl, recorder, operator):
            s.close()
    named = {(n.identity, n.message, n.key): n for n in report.named if n.flow == "ingress"}
    assert named[("a_pl", "put", spoof)].count == 3
    assert named[("a_pl", "put", foreign)].count == 2
    # the run folder
    written = [r for r in read_refusals(router.run_dir) if r.flow == "ingress"]
    assert [r.key for r in written if r.identity == "a_pl"][-5:] == [spoof] * 3 + [foreign] * 2
    assert all(abs(r.t - time.time()) < 600 for r in written)
    # roco status, with the operator's credentials given as an option
    assert router.security is not None
    out = cli(
        ["status", "--router", ep, "--credentials", str(router.security), "--counters-timeout", "0"], tmp_path
    )
    assert out.returncode == 1, out.stderr  # no agent is up
    (line,) = [ln for ln in out.stdout.splitlines() if ln.startswith("router")]
    assert f"a_pl put {spoof} ×3" in line and f"a_pl put {foreign} ×2" in line, line


def test_operator_tools_without_credentials_say_the_router_refused_them(
    router: Fleet, tmp_path: Path
) -> None:
    ep = router.endpoint
    commands = [
        ["status", "--router", ep],
        ["send", "--router", ep, "pour the jar into the bowl"],
        ["sniff", "--router", ep],
        ["fault", "show", "--router", ep],
    ]
    for args in commands:
        out = cli(args, tmp_path)
        assert out.returncode == 1, (args, out.stdout, out.stderr)
        assert out.stderr.count("\n") == 1, (args, out.stderr)
        assert f"roco: the router at {ep} refused the session for want of credentials" in out.stderr, args
        assert "--credentials DIR or ROCO_SECURITY=DIR" in out.stderr
    # the credentials from the environment instead
    assert router.security is not None
    out = cli(
        ["status", "--router", ep, "--counters-timeout", "0"], tmp_path, ROCO_SECURITY=str(router.security)
    )
    assert "router" in out.stdout and "refused" not in out.stderr, out.stderr
    # another deployment's credentials are refused as such
    other = tmp_path / "other"
    certs.issue(other, ["operator"])
    out = cli(["status", "--router", ep, "--credentials", str(other)], tmp_path)
    assert out.returncode == 1 and f"refused the credentials of 'operator' from {other}" in out.stderr
    # nothing listening: as before
    out = cli(["status", "--router", f"tcp/127.0.0.1:{free_port()}"], tmp_path)
    assert out.returncode == 1 and "no router answers at" in out.stderr
    # the router counted each refused session, with the client's address
    operator = open_client(ep)
    try:
        report = router_report(operator, 0)
    finally:
        operator.close()
    named = {n.key: n.count for n in report.named if n.message == "authenticate"}
    assert named.get("no credentials", 0) >= len(commands), report.named
    assert named.get("wrong password", 0) >= 1, report.named  # the other deployment's operator
    written = [r for r in read_refusals(router.run_dir) if r.message == "authenticate"]
    assert written and all(r.peer.startswith("tcp/127.0.0.1:") for r in written), written


def test_a_certificate_of_another_ca_is_refused_and_counted(tmp_path: Path) -> None:
    """Mutual TLS: a client (or a router trying to mesh) with a certificate the deployment's CA
    did not sign fails the TLS handshake; the router counts it (Zenoh logs no address for it)."""
    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=True)
    folder = fleet.security
    assert folder is not None
    fleet.start_router()
    try:
        other = tmp_path / "other"
        certs.issue(other, ["a_pl"])
        conf = zenoh.Config()
        conf.insert_json5("mode", '"client"')
        conf.insert_json5("connect/endpoints", f'["{fleet.endpoint}"]')
        conf.insert_json5("scouting/multicast/enabled", "false")
        password = (folder / "a_pl" / certs.PASSWORD).read_text().strip()
        conf.insert_json5("transport/auth/usrpwd/user", '"a_pl"')
        conf.insert_json5("transport/auth/usrpwd/password", f'"{password}"')
        tls = {
            "root_ca_certificate": str(folder / certs.CA_CERT),
            "connect_private_key": str(other / "a_pl" / certs.KEY),
            "connect_certificate": str(other / "a_pl" / certs.CERT),
            "enable_mtls": True,
        }
        conf.insert_json5("transport/link/tls", json.dumps(tls))
        with pytest.raises(zenoh.ZError):
            zenoh.open(conf)
        operator = open_client(fleet.endpoint)
        try:
            report = router_report(operator, 1)
        finally:
            operator.close()
    finally:
        fleet.stop()
        register(fleet.endpoint, None)
    (named,) = [n for n in report.named if n.message == "authenticate"]
    assert named.key.startswith("bad certificate: ") and named.count == 1, named
    assert "a client at authentication, bad certificate: " in summary(report)


def test_a_tls_client_without_a_certificate_is_refused_and_counted(tmp_path: Path) -> None:
    """Mutual TLS: a client that trusts the router's CA and knows a password but shows no
    certificate of its own fails the TLS handshake; the router counts it among the refusals,
    and ``roco status`` names it (Zenoh logs no address for it)."""
    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=True)
    folder = fleet.security
    assert folder is not None and fleet.endpoint.startswith("tls/")
    fleet.start_router()
    try:
        conf = zenoh.Config()
        conf.insert_json5("mode", '"client"')
        conf.insert_json5("connect/endpoints", f'["{fleet.endpoint}"]')
        conf.insert_json5("scouting/multicast/enabled", "false")
        password = (folder / "a_pl" / certs.PASSWORD).read_text().strip()
        conf.insert_json5("transport/auth/usrpwd/user", '"a_pl"')
        conf.insert_json5("transport/auth/usrpwd/password", f'"{password}"')
        conf.insert_json5(
            "transport/link/tls", json.dumps({"root_ca_certificate": str(folder / certs.CA_CERT)})
        )
        with pytest.raises(zenoh.ZError):
            zenoh.open(conf)
        operator = open_client(fleet.endpoint)
        try:
            report = router_report(operator, 1)
        finally:
            operator.close()
        out = cli(
            ["status", "--router", fleet.endpoint, "--credentials", str(folder), "--counters-timeout", "0"],
            tmp_path,
        )
    finally:
        fleet.stop()
        register(fleet.endpoint, None)
    assert report.counters.get("refused.authenticate") == 1, report.counters
    (named,) = [n for n in report.named if n.message == "authenticate"]
    assert (named.identity, named.key, named.count) == (UNKNOWN, "no certificate", 1)
    (written,) = [r for r in read_refusals(tmp_path) if r.message == "authenticate"]
    assert written.key == "no certificate"
    (status,) = [ln for ln in out.stdout.splitlines() if ln.startswith("router")]
    assert "refused 1: a client at authentication, no certificate ×1 (last " in status, status
    log = (tmp_path / "logs" / "router.stderr").read_text()
    assert "roco router: refused #1: a client authenticate (ingress) no certificate" in log


def test_a_session_matching_no_acl_subject_is_counted_as_refused(tmp_path: Path) -> None:
    """Credentials the router accepts but the ACL does not name (passwords.txt and acl.json
    disagree): the session may do nothing, and the router counts it once, by session id."""
    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=False)
    assert fleet.security is not None
    with (fleet.security / certs.PASSWORDS).open("a") as f:
        f.write("ghost:secret\n")
    fleet.start_router()
    try:
        conf = zenoh.Config()
        conf.insert_json5("mode", '"client"')
        conf.insert_json5("connect/endpoints", f'["{fleet.endpoint}"]')
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("transport/auth/usrpwd/user", '"ghost"')
        conf.insert_json5("transport/auth/usrpwd/password", '"secret"')
        ghost = zenoh.open(conf)
        ghost_id = str(ghost.info.zid())
        operator = open_client(fleet.endpoint)
        try:
            report = router_report(operator, 1)
        finally:
            operator.close()
            ghost.close()
    finally:
        fleet.stop()
        register(fleet.endpoint, None)
    assert report.counters.get("refused.session") == 1
    (named,) = [n for n in report.named if n.message == "session"]
    assert named.identity == UNKNOWN
    (written,) = [r for r in read_refusals(tmp_path) if r.message == "session"]
    assert written.session == ghost_id
    log = (tmp_path / "logs" / "router.stderr").read_text()
    assert f"refused #1: unnamed session {written.session} session (ingress)" in log
