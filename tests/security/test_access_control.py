"""Authentication and access control on a real router process (docs/security.md).

A router is spawned by the launcher (``Fleet.start_router``) with fresh credentials on a free
loopback port, once over TCP (user/password) and once over mutual TLS (certificate and
user/password); the clients are sessions of this test process. A message that must not arrive
is checked with a marker sent after it on the same session and allowed to arrive: once the
marker is in, the forbidden message would have been too. Every wait is on a queue or event with
a timeout; the router is ended by its PID.
"""

from __future__ import annotations

import json
import queue
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.session import alive_agents, open_client
from services.security import certs
from services.security.context import register

WAIT_S = 10.0


@pytest.fixture(scope="module", params=["tcp", "tls"])
def router(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    run_dir = tmp_path_factory.mktemp(f"acl-{request.param}")
    (run_dir / "logs").mkdir()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=True, tls=request.param == "tls")
    assert fleet.security is not None
    fleet.start_router()
    yield fleet
    fleet.stop()
    register(fleet.endpoint, None)


def raw_client(
    endpoint: str, *, user: str | None = None, password: str | None = None, tls: dict | None = None
) -> zenoh.Config:
    """A client configuration built by hand (no credentials looked up)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if user is not None:
        conf.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(password or ""))
    if tls is not None:
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    return conf


def tls_of(folder: Path, name: str) -> dict:
    return {
        "root_ca_certificate": str(folder / certs.CA_CERT),
        "connect_private_key": str(folder / name / certs.KEY),
        "connect_certificate": str(folder / name / certs.CERT),
        "enable_mtls": True,
    }


def refused(conf: zenoh.Config) -> bool:
    try:
        session = zenoh.open(conf)
    except zenoh.ZError:
        return True
    session.close()
    return False


class Inbox:
    """Keys of the samples a subscriber got, waitable."""

    def __init__(self) -> None:
        self.keys: list[str] = []
        self.q: queue.SimpleQueue[str] = queue.SimpleQueue()

    def __call__(self, sample: zenoh.Sample) -> None:
        self.keys.append(str(sample.key_expr))
        self.q.put(str(sample.key_expr))

    def wait_for(self, key: str, timeout: float = WAIT_S) -> bool:
        """Whether ``key`` arrives within ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                if self.q.get(timeout=left) == key:
                    return True
            except queue.Empty:
                break
        return False


def routed(sender: zenoh.Session, key: str, *inboxes: Inbox) -> None:
    """Put ``key`` from ``sender`` until every inbox got it: the subscribers' declarations have
    reached the router and what ``sender`` puts next is routed to them, in order."""
    deadline = time.monotonic() + WAIT_S
    pending = list(inboxes)
    while pending:
        if time.monotonic() > deadline:
            pytest.fail(f"{key} was not routed within {WAIT_S:.0f} s")
        sender.put(key, b"marker")
        pending = [i for i in pending if not i.wait_for(key, 0.2)]


def test_unauthenticated_client_cannot_connect(router: Fleet) -> None:
    folder = router.security
    assert folder is not None
    ep = router.endpoint
    password = (folder / "a_pl" / certs.PASSWORD).read_text().strip()
    tls = tls_of(folder, "a_pl") if ep.startswith("tls/") else None
    assert refused(raw_client(ep, tls=tls))  # no user/password
    assert refused(raw_client(ep, user="a_pl", password="not-" + password, tls=tls))
    assert refused(raw_client(ep, user="nobody", password=password, tls=tls))
    assert not refused(raw_client(ep, user="a_pl", password=password, tls=tls))  # the right ones do


def test_tls_needs_a_client_certificate_of_the_deployment_ca(router: Fleet, tmp_path: Path) -> None:
    folder = router.security
    assert folder is not None
    if not router.endpoint.startswith("tls/"):
        pytest.skip("TLS only")
    ep, pw = router.endpoint, (folder / "a_pl" / certs.PASSWORD).read_text().strip()
    no_cert = {"root_ca_certificate": str(folder / certs.CA_CERT), "enable_mtls": True}
    assert refused(raw_client(ep, user="a_pl", password=pw, tls=no_cert))
    other = tmp_path / "other"
    certs.issue(other, ["a_pl"])  # same name, another CA
    foreign = tls_of(other, "a_pl") | {"root_ca_certificate": str(folder / certs.CA_CERT)}
    assert refused(raw_client(ep, user="a_pl", password=pw, tls=foreign))


def test_a_certificate_of_another_identity_gets_no_rights(router: Fleet) -> None:
    """mTLS subjects need both user name and common name: a_pl's password with a_km's
    certificate connects (both are valid) but may do nothing. (The forbidden put and the marker
    come from different sessions: their order at the router is not guaranteed, so the marker is
    routed only after the forbidden put was sent and flushed by closing its session.)"""
    folder = router.security
    assert folder is not None
    if not router.endpoint.startswith("tls/"):
        pytest.skip("TLS only")
    ep = router.endpoint
    recorder = open_client(ep, identity="recorder")
    km = open_client(ep, identity="a_km")
    try:
        seen = Inbox()
        recorder.declare_subscriber(keys.FIPA_ALL, seen)
        routed(km, keys.fipa_key("C4", "a_km", "a_pl"), seen)
        pw = (folder / "a_pl" / certs.PASSWORD).read_text().strip()
        mixed = zenoh.open(raw_client(ep, user="a_pl", password=pw, tls=tls_of(folder, "a_km")))
        for _ in range(10):
            mixed.put(keys.fipa_key("C4", "a_pl", "a_km"), b"mixed")
        mixed.close()
        routed(km, keys.fipa_key("C6", "a_km", "a_ta"), seen)
        assert keys.fipa_key("C4", "a_pl", "a_km") not in seen.keys
    finally:
        km.close()
        recorder.close()


def test_an_agent_cannot_send_outside_its_channels_nor_as_another(router: Fleet) -> None:
    ep = router.endpoint
    recorder = open_client(ep, identity="recorder")
    km = open_client(ep, identity="a_km")
    pl = open_client(ep, identity="a_pl")
    try:
        everything, km_inbox = Inbox(), Inbox()
        recorder.declare_subscriber(keys.FIPA_ALL, everything)
        km.declare_subscriber(keys.inbox_key("a_km"), km_inbox)
        forbidden = [
            keys.fipa_key("C1", "a_pl", "a_ta"),  # C1 is a_co–a_ta: not a_pl's channel
            keys.fipa_key("C1", "a_co", "a_ta"),  # … nor as a_co
            keys.fipa_key("C4", "a_km", "a_pl"),  # its own channel, but as a_km
            keys.fipa_key("C6", "a_pl", "a_km"),  # to a_km on a_km's channel with a_ta
        ]
        allowed = keys.fipa_key("C4", "a_pl", "a_km")
        routed(pl, allowed, everything, km_inbox)
        for key in forbidden:
            pl.put(key, b"forged")
        routed(pl, allowed, everything, km_inbox)  # after the forged ones, on the same session
        assert not set(forbidden) & set(everything.keys)
        assert not set(forbidden) & set(km_inbox.keys)
    finally:
        for s in (pl, km, recorder):
            s.close()


def test_ag_ex_s_simulation_time_reaches_every_agent_and_no_other_agent_says_it(router: Fleet) -> None:
    ep = router.endpoint
    ex = open_client(ep, identity="ag_ex")
    pl = open_client(ep, identity="a_pl")
    km = open_client(ep, identity="a_km")
    try:
        payloads: list[bytes] = []
        inbox = Inbox()

        def heard(sample: zenoh.Sample) -> None:
            payloads.append(sample.payload.to_bytes())
            inbox(sample)

        km.declare_subscriber(keys.SIM_CLOCK, heard)  # a_km's clock follows the simulation
        routed(ex, keys.SIM_CLOCK, inbox)
        pl.put(keys.SIM_CLOCK, b"forged")  # a_pl may hear the simulation's time, not say it
        routed(ex, keys.SIM_CLOCK, inbox)
        assert payloads and b"forged" not in payloads
    finally:
        for s in (km, pl, ex):
            s.close()


def test_an_identity_without_recorder_rights_sees_nothing(router: Fleet) -> None:
    ep = router.endpoint
    pl = open_client(ep, identity="a_pl")
    km = open_client(ep, identity="a_km")
    co = open_client(ep, identity="a_co")
    try:
        snooped, inbox = Inbox(), Inbox()
        # refused by the router: nothing is routed for it; the session hands it only what the
        # router delivers for a_pl's own inbox (local dispatch), never the others' traffic
        pl.declare_subscriber(keys.FIPA_ALL, snooped)
        pl.declare_subscriber(keys.inbox_key("a_pl"), inbox)
        routed(co, keys.fipa_key("C3", "a_co", "a_pl"), inbox)
        co.put(keys.fipa_key("C1", "a_co", "a_ta"), b"not for a_pl")
        routed(co, keys.fipa_key("C3", "a_co", "a_pl"), inbox)
        routed(km, keys.fipa_key("C4", "a_km", "a_pl"), inbox)
        assert set(snooped.keys) <= {keys.fipa_key("C3", "a_co", "a_pl"), keys.fipa_key("C4", "a_km", "a_pl")}
        assert keys.fipa_key("C1", "a_co", "a_ta") not in inbox.keys
    finally:
        for s in (pl, km, co):
            s.close()


def test_liveliness_token_only_under_its_own_name(router: Fleet) -> None:
    ep = router.endpoint
    op = open_client(ep)  # operator
    pl = open_client(ep, identity="a_pl")
    seen: queue.SimpleQueue[str] = queue.SimpleQueue()
    done = threading.Event()

    def on_token(sample: zenoh.Sample) -> None:
        seen.put(str(sample.key_expr))
        if str(sample.key_expr) == keys.alive_key("a_pl"):
            done.set()

    try:
        op.liveliness().declare_subscriber(keys.ALIVE_ALL, on_token, history=True)
        fake = pl.liveliness().declare_token(keys.alive_key("a_km"))
        real = pl.liveliness().declare_token(keys.alive_key("a_pl"))
        assert done.wait(WAIT_S)
        tokens = []
        while not seen.empty():
            tokens.append(seen.get())
        assert keys.alive_key("a_km") not in tokens
        # a liveliness get through the router finds the real token only (on a loaded machine it
        # may take more than the get's own 1 s: asked again until the deadline)
        deadline = time.monotonic() + WAIT_S
        while not (found := alive_agents(op)) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert found == {"a_pl"}
        fake.undeclare()
        real.undeclare()
    finally:
        pl.close()
        op.close()


def test_operator_cannot_speak_fipa(router: Fleet) -> None:
    ep = router.endpoint
    op = open_client(ep)
    recorder = open_client(ep, identity="recorder")
    try:
        everything = Inbox()
        recorder.declare_subscriber(keys.FIPA_ALL, everything)
        recorder.declare_subscriber(keys.HUMAN_IN, everything)
        recorder.declare_subscriber(keys.RECORDER_SYNC, everything)
        routed(op, keys.RECORDER_SYNC, everything)
        op.put(keys.fipa_key("C2", "a_hi", "a_co"), b"forged")
        op.put(keys.HUMAN_IN, b"allowed to the operator, but the recorder may not hear it")
        routed(op, keys.RECORDER_SYNC, everything)
        assert set(everything.keys) == {keys.RECORDER_SYNC}
    finally:
        op.close()
        recorder.close()


def test_a_revoked_identity_is_refused_after_the_router_restarts(tmp_path: Path) -> None:
    from services.deploy.deploy import revoke_identity
    from services.spec.model import DEFAULT_SPEC, load

    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=True)
    assert fleet.security is not None
    kept = tmp_path / "kept-a_pl"
    shutil.copytree(fleet.security / "a_pl", kept)
    revoke_identity(fleet.security, load(DEFAULT_SPEC), "a_pl")
    assert "a_pl" not in certs.read_passwords(fleet.security)
    fleet.start_router()
    try:
        pw = (kept / certs.PASSWORD).read_text().strip()
        assert refused(raw_client(fleet.endpoint, user="a_pl", password=pw))
        open_client(fleet.endpoint, identity="a_km").close()  # the others still connect
    finally:
        fleet.stop()
        register(fleet.endpoint, None)


def test_the_operator_gets_a_report_a_hi_gave_before_it_listened(router: Fleet) -> None:
    """a_hi's advanced publisher of reports and the operator's follower (services/runtime/reports.py)
    have what they need: a report put before the operator's session subscribed comes from
    a_hi's cache, through the router's access control."""
    from services.runtime.human import HumanReport, ReportKind
    from services.runtime.reports import follow_reports
    from services.runtime.transport import ZenohTransport

    hi = ZenohTransport([router.endpoint], identity="a_hi")
    op = open_client(router.endpoint)
    got: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
    try:
        said = HumanReport(request_id="r1", kind=ReportKind.SUCCEEDED, text="done")
        hi.publish(keys.HUMAN_OUT, msgspec.json.encode(said))
        follow_reports(op, got.put)
        assert got.get(timeout=WAIT_S) == said
    finally:
        op.close()
        hi.close()


def test_ag_ex_renders_its_camera_for_roco_ros2_and_not_for_another_agent(router: Fleet) -> None:
    """ag_ex's camera feed (a stand-in renderer) on a router with access control: roco ros2's
    subscriber matches ag_ex's publisher (ag_ex learns of it: it renders, ros2 gets the images);
    a_pl's subscriber is refused, so once ros2 leaves ag_ex renders no more."""
    from services.agents.executor.camera_feed import CameraPublisher
    from tests.support.camera import Made, World

    ep = router.endpoint
    ex, ros2, pl = (open_client(ep, identity=i) for i in ("ag_ex", "ros2", "a_pl"))
    publisher = CameraPublisher(ex, World(), 20.0, make_camera=Made())
    try:
        camera = keys.camera_key("ag_ex")
        assert publisher.feed.idle.wait(WAIT_S)
        others, theirs = Inbox(), Inbox()
        pl.declare_subscriber(camera, others)
        sub = ros2.declare_subscriber(camera, theirs)
        assert theirs.wait_for(camera), "roco ros2 got no image"
        publisher.feed.idle.clear()
        sub.undeclare()
        assert publisher.feed.idle.wait(WAIT_S), "ag_ex renders on for a_pl, whose subscriber is refused"
        assert others.keys == []
    finally:
        publisher.close()
        for s in (pl, ros2, ex):
            s.close()
