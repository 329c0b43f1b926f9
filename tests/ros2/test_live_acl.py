"""An outside ROS 2 session under access control: zenoh-ros2-sdk (PyPI) as the identity
``ros2_peer`` (services/spec_check/acl.py ``ros2_peer_grants``), its credentials given as
rmw_zenoh takes them (``ZENOH_CONFIG_OVERRIDE``), on a router process with the fleet's access
control (TCP with user/password, and mutual TLS), beside ``roco ros2``'s face and a stand-in
a_hi (tests/ros2/test_live_face.py). It receives /joint_states, calls /roco/say and hears its
progress; what it puts or subscribes to under ``roco/**`` is refused by the router: never
delivered (a later call, answered through a_hi on the same session, is the marker) and
counted and named in the router's refusal report."""

from __future__ import annotations

import contextlib
import json
import queue
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.fleet.launcher import Fleet
from services.ros2 import messages
from services.ros2.face import JOINT_STATES, SAY_PROGRESS, Ros2Face
from services.runtime import keys
from services.runtime.session import open_client
from services.runtime.transport import ZenohTransport
from services.security import certs
from services.spec_check.acl import ROS2_PEER, _includes
from tests.ros2.test_live_face import StandInHi, face_and_sdk
from tests.security.test_refusals import router_report
from tests.support.router import router_fleet

sdk = pytest.importorskip("zenoh_ros2_sdk", reason="the loopback tests need zenoh-ros2-sdk (PyPI)")

TIMEOUT = 20.0
FORGED = ("roco/fipa/C9/x@ros2/a_hi", keys.HUMAN_IN)
"""What the ROS 2 session tries to put: a C9 request as a ROS 2 caller, a person's line."""


@pytest.fixture(scope="module", params=["tcp", "tls"])
def router(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    yield from router_fleet(
        tmp_path_factory, f"ros2_acl_{request.param}", acl=True, tls=request.param == "tls"
    )


def override(folder: Path, endpoint: str) -> str:
    """``ZENOH_CONFIG_OVERRIDE`` for :data:`ROS2_PEER`'s credentials in ``folder`` (roco
    deploy's files), as docs/ros2.md gives it to rmw_zenoh_cpp: user and password; over TLS
    also the router's endpoint, the deployment's CA and the identity's certificate and key."""
    password = (folder / ROS2_PEER / certs.PASSWORD).read_text().strip()
    pairs = {"transport/auth/usrpwd/user": ROS2_PEER, "transport/auth/usrpwd/password": password}
    if endpoint.startswith("tls/"):
        pairs |= {
            "connect/endpoints": [endpoint],
            "transport/link/tls/root_ca_certificate": str(folder / certs.CA_CERT),
            "transport/link/tls/connect_certificate": str(folder / ROS2_PEER / certs.CERT),
            "transport/link/tls/connect_private_key": str(folder / ROS2_PEER / certs.KEY),
            "transport/link/tls/enable_mtls": True,
        }
    return ";".join(f"{path}={json.dumps(value)}" for path, value in pairs.items())


@pytest.fixture(scope="module")
def setup(
    router: Fleet, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[Ros2Face, StandInHi, int]]:
    assert router.security is not None
    env = {"ZENOH_CONFIG_OVERRIDE": override(router.security, router.endpoint)}  # as rmw_zenoh reads it
    types = ["sensor_msgs/msg/JointState", messages.SAY_PROGRESS]
    folder = tmp_path_factory.mktemp("msgs")
    with face_and_sdk(router, frozenset({JOINT_STATES}), types, folder, env) as made:
        yield made


def _joint_states(router: Fleet, got: queue.SimpleQueue[Any]) -> Any:
    """Put ag_ex's snapshots until the SDK's subscriber has one JointState; that message."""
    state = ZenohTransport([router.endpoint], identity="ag_ex")
    snapshot = {"sim_time": 1.5, "joints": {"torso_0_joint": 0.25}, "grip": {}, "held": {}}
    try:
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            state.publish(keys.state_key("ag_ex"), msgspec.msgpack.encode(snapshot | {"links": {}}))
            with contextlib.suppress(queue.Empty):
                return got.get(timeout=0.2)
    finally:
        state.close()
    return None


def test_a_ros2_peer_gets_joint_states_calls_say_and_nothing_on_roco(
    setup: tuple[Ros2Face, StandInHi, int], router: Fleet
) -> None:
    _face, hi, port = setup
    got: queue.SimpleQueue[Any] = queue.SimpleQueue()
    sdk.ROS2Subscriber(
        "/joint_states", "sensor_msgs/msg/JointState", got.put, router_ip="127.0.0.1", router_port=port
    )
    msg = _joint_states(router, got)
    assert msg is not None, "no JointState reached the ros2_peer session within the timeout"
    assert (list(msg.name), list(msg.position)) == (["torso_0_joint"], [0.25])

    from zenoh_ros2_sdk.session import ZenohSession

    peer = ZenohSession.get_instance("127.0.0.1", port).session
    operator = open_client(router.endpoint)  # hears roco/**
    try:
        seen: queue.SimpleQueue[str] = queue.SimpleQueue()
        operator.declare_subscriber(f"{keys.PREFIX}/**", lambda s: seen.put(str(s.key_expr)))
        snooped: list[str] = []
        peer.declare_subscriber(f"{keys.PREFIX}/**", lambda s: snooped.append(str(s.key_expr)))
        before = router_report(operator, 0).counters.get("refused.ingress", 0)
        for key in FORGED:
            peer.put(key, b"forged")
        progress: queue.SimpleQueue[Any] = queue.SimpleQueue()
        sdk.ROS2Subscriber(
            f"/{SAY_PROGRESS}", messages.SAY_PROGRESS, progress.put, router_ip="127.0.0.1", router_port=port
        )
        # the marker: a call on the same session, put to a_hi by the face, answered through a_hi
        client = sdk.ROS2ServiceClient(
            "/roco/say", messages.SAY, router_ip="127.0.0.1", router_port=port, timeout=TIMEOUT
        )
        response = client.call(sentence="bring me the cup")
        assert response is not None and (response.ok, response.report) == (True, "done: bring me the cup")
        assert hi.sentences.get(timeout=TIMEOUT) == "bring me the cup"
        assert [progress.get(timeout=TIMEOUT).state for _ in range(3)] == [
            "requested",
            "accepted",
            "succeeded",
        ]
        keys_seen = _drain_until(seen, f"{keys.FIPA_PREFIX}C9/$*@ros2/a_hi")
        report = router_report(operator, before + len(FORGED))
    finally:
        operator.close()
    assert not set(FORGED) & set(keys_seen), keys_seen  # refused: never delivered
    # the router delivers it nothing of roco/** (a_hi's answers to the face on C9 among them);
    # its own puts reach its own subscriber within the session, not through the router
    assert [k for k in snooped if k not in FORGED] == [], snooped
    named = {(n.identity, n.message, n.key) for n in report.named if n.flow == "ingress"}
    assert {(ROS2_PEER, "put", key) for key in FORGED} <= named, named


def _drain_until(seen: queue.SimpleQueue[str], pattern: str) -> list[str]:
    """The keys ``seen`` got up to and including the first that ``pattern`` includes."""
    keys_seen: list[str] = []
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline:
        with contextlib.suppress(queue.Empty):
            keys_seen.append(seen.get(timeout=0.2))
            if _includes(pattern, keys_seen[-1]):
                return keys_seen
    pytest.fail(f"nothing on {pattern} within {TIMEOUT:.0f} s: {keys_seen}")
