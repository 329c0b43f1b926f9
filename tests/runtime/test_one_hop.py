"""One hop: agents' sessions on one host link to each other directly (Zenoh peers), the router
kept for discovery; with access control on mutual TLS each peer applies the specification's
ACL to what crosses its links, so a forged communicate sent over a direct link is dropped as the
router would drop it (services/runtime/transport.py ``member_config``)."""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.transport import ZenohTransport
from services.runtime.zenoh_config import member_config, one_hop, open_session, peer_access_control
from services.security import certs
from tests.support.router import router_fleet

WAIT_S = 10.0


@pytest.fixture(scope="module")
def open_fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    yield from router_fleet(tmp_path_factory, "one-hop-open")


@pytest.fixture(scope="module")
def tls_fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    yield from router_fleet(tmp_path_factory, "one-hop-tls", acl=True, tls=True)


class Inbox:
    """Keys and payloads a transport's subscriber got, waitable."""

    def __init__(self) -> None:
        self.got: list[tuple[str, bytes]] = []
        self.q: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()

    def __call__(self, key: str, payload: bytes) -> None:
        self.got.append((key, payload))
        self.q.put((key, payload))

    def wait_for(self, payload: bytes, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                if self.q.get(timeout=left)[1] == payload:
                    return True
            except queue.Empty:
                break
        return False


def delivered(sender: ZenohTransport, key: str, inbox: Inbox, payload: bytes = b"marker") -> None:
    """Publish ``payload`` on ``key`` until ``inbox`` got it (the subscriber's declaration has
    reached the sender): what the sender puts next on that key follows it, in order."""
    deadline = time.monotonic() + WAIT_S
    while not inbox.wait_for(payload, 0.2):
        if time.monotonic() > deadline:
            pytest.fail(f"{key} was not delivered within {WAIT_S:.0f} s")
        sender.publish(key, payload)


def linked(a: zenoh.Session, b: zenoh.Session) -> None:
    """Wait until ``a`` has a direct link to ``b`` (and b to a)."""
    deadline = time.monotonic() + WAIT_S
    while b.zid() not in a.info.peers_zid() or a.zid() not in b.info.peers_zid():
        if time.monotonic() > deadline:
            pytest.fail("the two peers did not link to each other")
        time.sleep(0.05)


def test_one_hop_only_on_this_hosts_loopback_and_with_access_control_only_on_tls(tmp_path: Path) -> None:
    assert one_hop(["tcp/127.0.0.1:7447"], None)
    assert not one_hop(["tls/localhost:7447"], tmp_path)  # one identity's folder: no peers' passwords
    (tmp_path / "acl.json").write_text("{}")
    (tmp_path / "passwords.txt").write_text("")
    assert one_hop(["tls/localhost:7447"], tmp_path)
    assert not one_hop(["tcp/127.0.0.1:7447"], tmp_path)  # usrpwd over TCP: the router path
    assert not one_hop(["tcp/router:7447"], None)  # compose: another container's router
    assert not one_hop(["tls/10.0.0.2:7447"], tmp_path)  # another host
    assert not one_hop([], None)


def test_a_router_path_is_kept_where_configured(open_fleet: Fleet) -> None:
    conf = member_config([open_fleet.endpoint], links="router")
    session = open_session(conf)
    try:
        assert str(session.info.routers_zid()) and session.info.peers_zid() == []
    finally:
        session.close()


def test_peers_link_directly_and_go_on_while_the_router_is_down(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    fleets = router_fleet(tmp_path_factory, "one-hop-router-down")
    fleet = next(fleets)
    a = ZenohTransport([fleet.endpoint], links="peer")
    b = ZenohTransport([fleet.endpoint], links="peer")
    try:
        linked(a.session, b.session)
        inbox = Inbox()
        key = keys.fipa_key("C2", "a_co", "a_hi")
        b.subscribe(keys.inbox_key("a_hi"), inbox)
        delivered(a, key, inbox)
        router = fleet.processes["router"]
        router.kill()
        router.wait(timeout=WAIT_S)
        a.publish(key, b"without the router")
        assert inbox.wait_for(b"without the router", WAIT_S)
    finally:
        a.close()
        b.close()
        fleets.close()


def test_on_tls_agents_link_directly_and_each_drops_what_the_acl_forbids(tls_fleet: Fleet) -> None:
    """a_pl's session links to a_km's directly; a_pl's puts as a_co, or on a channel it does
    not have, never reach a_km — even from a peer whose own session applies no access control
    (a planted one holding a_pl's credentials), so it is a_km's session that drops them."""
    ep = tls_fleet.endpoint
    km = ZenohTransport([ep], identity="a_km", links="peer")
    pl = ZenohTransport([ep], identity="a_pl", links="peer")
    conf = member_config([ep], identity="a_pl", links="peer")
    conf.insert_json5("access_control", json.dumps({"enabled": False}))
    planted = open_session(conf)
    try:
        linked(km.session, pl.session)
        linked(km.session, planted)
        inbox = Inbox()
        km.subscribe(keys.inbox_key("a_km"), inbox)
        allowed = keys.fipa_key("C4", "a_pl", "a_km")
        delivered(pl, allowed, inbox)
        forged = [keys.fipa_key("C4", "a_co", "a_km"), keys.fipa_key("C7", "a_pl", "a_km")]
        for key in forged:
            planted.put(key, b"forged", congestion_control=zenoh.CongestionControl.BLOCK)
        planted.put(allowed, b"after the forged ones", congestion_control=zenoh.CongestionControl.BLOCK)
        assert inbox.wait_for(b"after the forged ones", WAIT_S)  # same link, in order
        assert not {k for k, p in inbox.got if p == b"forged"}
    finally:
        planted.close()
        pl.close()
        km.close()


def test_a_peer_without_the_deployments_certificate_cannot_link(tls_fleet: Fleet, tmp_path: Path) -> None:
    """A peer holding a_pl's password but a certificate of another CA is refused by an agent's
    session it connects to directly (on the port that session listens on for its peers)."""
    other = tmp_path / "other"
    certs.issue(other, ["a_pl"])
    folder = tls_fleet.security
    assert folder is not None
    km_port = free_port()
    km_conf = member_config([tls_fleet.endpoint], identity="a_km", links="peer")
    km_conf.insert_json5("listen/endpoints", json.dumps([f"tls/127.0.0.1:{km_port}"]))
    km = open_session(km_conf)
    try:

        def direct(identity_folder: Path) -> zenoh.Config:
            conf = member_config([f"tls/127.0.0.1:{km_port}"], identity="a_pl", links="peer", security=folder)
            tls = {
                "root_ca_certificate": str(folder / certs.CA_CERT),
                "connect_private_key": str(identity_folder / "a_pl" / certs.KEY),
                "connect_certificate": str(identity_folder / "a_pl" / certs.CERT),
                "enable_mtls": True,
            }
            conf.insert_json5("transport/link/tls", json.dumps(tls))
            conf.insert_json5("listen/endpoints", "[]")
            conf.insert_json5("connect/timeout_ms", "2000")
            conf.insert_json5("connect/exit_on_failure", "true")
            return conf

        open_session(direct(folder)).close()  # the deployment's own certificate links
        with pytest.raises(zenoh.ZError):
            open_session(direct(other))
    finally:
        km.close()


def test_a_peers_acl_matches_by_certificate_and_lets_the_router_relay() -> None:
    acl = {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {
                "id": "a/ingress/put",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put"],
                "key_exprs": ["k"],
            }
        ],
        "subjects": [{"id": "a", "usernames": ["a"], "cert_common_names": ["a"]}],
        "policies": [{"id": "a", "rules": ["a/ingress/put"], "subjects": ["a"]}],
    }
    peer = peer_access_control(acl)
    assert peer["default_permission"] == "deny"
    assert {"id": "a", "cert_common_names": ["a"]} in peer["subjects"]
    assert {"id": "router/link", "cert_common_names": ["router"]} in peer["subjects"]
    relay = next(r for r in peer["rules"] if r["id"] == "router/relays")
    assert relay["key_exprs"] == ["**", "**/@adv/**"] and set(relay["flows"]) == {"ingress", "egress"}
    assert acl["subjects"] == [{"id": "a", "usernames": ["a"], "cert_common_names": ["a"]}]  # unchanged


def test_a_recorder_started_later_fetches_what_a_peer_sent_from_its_cache(tls_fleet: Fleet) -> None:
    """The recorder is the router's client; what an agent linked directly put before it started
    reaches it from the agent's cache (zenoh-ext, below ``<key>/@adv/``), through the router's
    link, which each peer's ACL lets carry that too."""
    ep = tls_fleet.endpoint
    ta = ZenohTransport([ep], identity="a_ta", links="peer")
    co = ZenohTransport([ep], identity="a_co", links="peer")
    recorder: ZenohTransport | None = None
    try:
        linked(ta.session, co.session)
        inbox = Inbox()
        co.subscribe(keys.inbox_key("a_co"), inbox)
        key = keys.fipa_key("C1", "a_ta", "a_co")
        delivered(ta, key, inbox, b"m0")
        for payload in (b"m1", b"m2"):
            ta.publish(key, payload)
        assert inbox.wait_for(b"m2", WAIT_S)
        recorder = ZenohTransport([ep], identity="recorder")
        got: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        recorder.subscribe_recovering(keys.FIPA_ALL, lambda arrival: got.put(arrival.payload))
        fetched = set()
        deadline = time.monotonic() + WAIT_S
        while not {b"m1", b"m2"} <= fetched:
            left = deadline - time.monotonic()
            assert left > 0, f"from the cache: {fetched}"
            try:
                fetched.add(got.get(timeout=left))
            except queue.Empty:
                break
        assert {b"m1", b"m2"} <= fetched
    finally:
        if recorder is not None:
            recorder.close()
        co.close()
        ta.close()


def test_the_routers_link_may_carry_every_kind_of_message_the_acl_names() -> None:
    """transport.py lists Zenoh's message kinds for the router's link (the runtime cannot import
    the ACL generator above it); the list is the generator's ``Message``."""
    import typing

    from services.runtime.zenoh_config import ACL_MESSAGES
    from services.spec_check.acl import Message

    assert set(ACL_MESSAGES) == set(typing.get_args(Message))
