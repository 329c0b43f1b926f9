"""The ROS 2 face (services/ros2/face.py) against zenoh-ros2-sdk, an independent ROS 2-over-Zenoh
client from PyPI, on a router of its own (no access control: the SDK has no credentials) with a
stand-in a_hi that answers C9 as a_hi does (agree, then inform a SentenceReport). The SDK
computes the type hashes itself from the .msg texts (given offline: tests/ros2/sdk.py), so a
message that arrives and a call that is answered prove that both sides agree on key, hash, CDR
and attachment. Every refusal is answered at once and counted; the face answers after each."""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import pytest
import zenoh

from services.agents.executor.camera_feed import CameraPublisher
from services.fleet.launcher import Fleet
from services.ros2 import messages
from services.ros2.face import (
    CAMERA,
    CAMERA_INFO,
    IMAGE_RAW,
    JOINT_STATES,
    MAX_CALL_S,
    SAY_PROGRESS,
    TASK_STATE,
    TF,
    FaceConfig,
    Ros2Face,
    say_store,
    summary,
)
from services.runtime import keys
from services.runtime.counters import ask_counters
from services.runtime.session import open_client
from services.runtime.transport import ZenohTransport
from services.spec.model import default_spec
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.l_hc import Sentence, SentenceReport
from tests.ros2.sdk import close_session, use_offline, write_definitions
from tests.support.camera import Made, World
from tests.support.router import router_fleet

sdk = pytest.importorskip("zenoh_ros2_sdk", reason="the loopback tests need zenoh-ros2-sdk (PyPI)")

TIMEOUT = 20.0
BAD_HASH = "RIHS01_" + "0" * 64


@pytest.fixture(scope="module")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    yield from router_fleet(tmp_path_factory, "ros2_face")


class StandInHi:
    """a_hi's side of C9 as the face sees it: every request a Sentence, answered agree then
    inform (``succeeded``: "done: <sentence>"), unless ``hold`` is set: then only agree; with
    ``agree_twice`` set, a second agree (outside fipa-request) before the inform."""

    def __init__(self, transport: ZenohTransport) -> None:
        self.transport = transport
        self.sentences: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.hold = threading.Event()
        self.agree_twice = threading.Event()
        transport.subscribe(f"{keys.FIPA_PREFIX}C9/$*@ros2/a_hi", self._take)

    def _take(self, key: str, payload: bytes) -> None:
        msg = decode(payload)
        term = decode_content(msg.language, msg.content)
        assert isinstance(term, Sentence) and msg.sender is not None
        self.sentences.put(term.text)
        self._answer(msg, Performative.AGREE, SentenceReport(kind="accepted", text="ok"))
        if self.agree_twice.is_set():
            self._answer(msg, Performative.AGREE, SentenceReport(kind="succeeded", text="not yet"))
        if not self.hold.is_set():
            self._answer(
                msg, Performative.INFORM, SentenceReport(kind="succeeded", text=f"done: {term.text}")
            )

    def _answer(self, msg: Communicate, performative: Performative, report: SentenceReport) -> None:
        assert msg.sender is not None
        language, content = encode_content(report)
        answer = Communicate(
            performative=performative,
            sender=AgentIdentifier("a_hi"),
            receiver=(msg.sender,),
            content=content,
            language=language,
            encoding="msgpack",
            protocol="fipa-request",
            conversation_id=msg.conversation_id,
            in_reply_to=msg.reply_with,
        )
        self.transport.publish(keys.fipa_key("C9", "a_hi", msg.sender.name), encode(answer))


@contextlib.contextmanager
def face_and_sdk(
    router: Fleet, topics: frozenset[str], types: list[str], folder: Path, env: dict[str, str] | None = None
) -> Iterator[tuple[Ros2Face, StandInHi, int]]:
    """A started Ros2Face (identity ``ros2``, publishing ``topics``) and a stand-in a_hi on
    ``router``, and zenoh-ros2-sdk fed the definitions of ``types`` offline from ``folder``,
    with ``env`` set while it runs; yields (face, a_hi, the router's port); closes all after."""
    port = int(router.endpoint.rsplit(":", 1)[1])
    face_transport = ZenohTransport([router.endpoint], identity="ros2")
    hi = StandInHi(ZenohTransport([router.endpoint], identity="a_hi"))
    face = Ros2Face(face_transport, default_spec(), FaceConfig(topics=topics))
    face.bind()
    face.start()
    mp = pytest.MonkeyPatch()
    for name, value in (env or {}).items():
        mp.setenv(name, value)
    write_definitions(folder, types)
    use_offline(folder, mp)
    try:
        yield face, hi, port
    finally:
        close_session()
        mp.undo()
        face.stop()
        face_transport.close()
        hi.transport.close()


@pytest.fixture(scope="module")
def setup(
    router: Fleet, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[Ros2Face, StandInHi, int]]:
    types = [
        "sensor_msgs/msg/JointState",
        "tf2_msgs/msg/TFMessage",
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CameraInfo",
        messages.SAY_PROGRESS,
    ]
    topics = frozenset({JOINT_STATES, TF, TASK_STATE, CAMERA})
    with face_and_sdk(router, topics, types, tmp_path_factory.mktemp("msgs")) as made:
        yield made


def _client(port: int, **kw: Any) -> Any:
    return sdk.ROS2ServiceClient("/roco/say", messages.SAY, router_ip="127.0.0.1", router_port=port, **kw)


def _counters(router: Fleet) -> dict[str, int]:
    session = open_client(router.endpoint)
    try:
        return ask_counters(session, {"ros2"}, timeout=TIMEOUT)["ros2"].counters
    finally:
        session.close()


def _raw_call(port: int, key: str, payload: bytes, attachment: bytes | None) -> Any:
    """A call put together by hand on the SDK's session: the response (CDR decoded; its
    attachment must carry the request's sequence number and GID: rmw_zenoh's design document,
    "Service Servers"), or the error reply's text."""
    from zenoh_ros2_sdk.session import ZenohSession

    session = ZenohSession.get_instance("127.0.0.1", port).session
    replies = session.get(
        key, payload=payload, attachment=attachment, target=zenoh.QueryTarget.ALL_COMPLETE, timeout=TIMEOUT
    )
    for reply in replies:
        if reply.ok is not None:
            from zenoh_ros2_sdk.attachment import Attachment

            assert attachment is not None and reply.ok.attachment is not None
            sent, got = (
                Attachment.from_bytes(attachment),
                Attachment.from_bytes(reply.ok.attachment.to_bytes()),
            )
            assert (got.sequence_id, got.gid) == (
                sent.sequence_id,
                sent.gid,
            ) and got.timestamp_ns >= sent.timestamp_ns
            return say_store().deserialize_cdr(reply.ok.payload.to_bytes(), f"{messages.SAY}_Response")
        return reply.err.payload.to_bytes().decode()
    return None


def test_joint_states_reach_an_independent_ros2_subscriber(
    setup: tuple[Ros2Face, StandInHi, int], router: Fleet
) -> None:
    face, _hi, port = setup
    got: queue.SimpleQueue[Any] = queue.SimpleQueue()
    sub = sdk.ROS2Subscriber(
        "/joint_states", "sensor_msgs/msg/JointState", got.put, router_ip="127.0.0.1", router_port=port
    )
    assert sub.keyexpr == face._pubs[JOINT_STATES].endpoint.key  # the SDK's own hash equals ours
    frames: queue.SimpleQueue[Any] = queue.SimpleQueue()
    sdk.ROS2Subscriber("/tf", "tf2_msgs/msg/TFMessage", frames.put, router_ip="127.0.0.1", router_port=port)
    snapshot = {"sim_time": 2.25, "joints": {"torso_0_joint": 0.5, "right_arm_0_joint": -1.0}}
    jar = [[0.6, -0.1, 0.9], [0.9, 0.1, 0.2, 0.3], "world"]  # a Pose: position, (w, x, y, z), frame
    snapshot |= {"grip": {}, "held": {}, "held_object": {}, "links": {"jar": jar}}
    state = ZenohTransport([router.endpoint], identity="ag_ex")
    try:
        deadline = time.monotonic() + TIMEOUT
        msg = None
        while msg is None and time.monotonic() < deadline:  # until the subscriber is matched
            state.publish(keys.state_key("ag_ex"), msgspec.msgpack.encode(snapshot))
            with contextlib.suppress(queue.Empty):
                msg = got.get(timeout=0.2)
    finally:
        state.close()
    assert msg is not None, "no JointState within the timeout"
    assert list(msg.name) == ["torso_0_joint", "right_arm_0_joint"]
    assert list(msg.position) == [0.5, -1.0]
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (2, 250_000_000)
    assert face.counters["published.joint_states"] >= 1
    tf = frames.get(timeout=TIMEOUT).transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("world", "jar")
    t, r = tf.transform.translation, tf.transform.rotation
    assert (t.x, t.y, t.z, r.w, r.x, r.y, r.z) == (0.6, -0.1, 0.9, 0.9, 0.1, 0.2, 0.3)


def test_camera_images_reach_an_independent_ros2_subscriber_rendered_only_while_it_subscribes(
    setup: tuple[Ros2Face, StandInHi, int], router: Fleet
) -> None:
    """A stand-in ag_ex (its camera feed, a stand-in renderer): nothing rendered before a ROS 2
    node subscribes (the face does not subscribe to ag_ex's images then); the SDK then gets
    Image and CameraInfo with the frame's robot time; once it leaves, ag_ex stops rendering."""
    from velma.perception.cloud import Intrinsics

    face, _hi, port = setup
    made, world = Made(), World()
    ag_ex = ZenohTransport([router.endpoint], identity="ag_ex")
    publisher = CameraPublisher(ag_ex.session, world, 20.0, make_camera=made)
    subs: list[Any] = []
    try:
        assert publisher.feed.idle.wait(TIMEOUT) and made.cameras == []
        images: queue.SimpleQueue[Any] = queue.SimpleQueue()
        infos: queue.SimpleQueue[Any] = queue.SimpleQueue()
        ros = {"router_ip": "127.0.0.1", "router_port": port}
        subs.append(sdk.ROS2Subscriber("/head_camera/image_raw", "sensor_msgs/msg/Image", images.put, **ros))
        assert subs[0].keyexpr == face._pubs[IMAGE_RAW].endpoint.key  # the SDK's own hash equals ours
        subs.append(
            sdk.ROS2Subscriber("/head_camera/camera_info", "sensor_msgs/msg/CameraInfo", infos.put, **ros)
        )
        assert subs[1].keyexpr == face._pubs[CAMERA_INFO].endpoint.key
        image, info = images.get(timeout=TIMEOUT), infos.get(timeout=TIMEOUT)
        publisher.feed.idle.clear()
        for sub in subs:
            sub.close()
        assert publisher.feed.idle.wait(TIMEOUT), "ag_ex still renders after the ROS 2 node left"
    finally:
        publisher.close()
        ag_ex.close()
    assert (image.encoding, image.width, image.height, image.step) == ("rgb8", 320, 240, 960)
    data = np.asarray(image.data, dtype=np.uint8).reshape(240, 320, 3)
    assert list(data[5, :4, 0]) == [0, 1, 2, 3] and image.header.frame_id == "head_camera_optical_frame"
    stamps = [s.header.stamp.sec + s.header.stamp.nanosec * 1e-9 for s in (image, info)]
    assert all(min(abs(t - w) for w in world.times) < 1e-6 for t in stamps)  # a frame's robot time
    k = Intrinsics.from_fovy(43.0, 320, 240)
    assert list(info.k) == pytest.approx([k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1])
    assert (info.width, info.height, info.header.frame_id) == (320, 240, "head_camera_optical_frame")
    assert face.counters["published.image_raw"] >= 1 and face.counters["published.camera_info"] >= 1


def test_a_sentence_is_answered_with_a_his_report_and_its_progress(
    setup: tuple[Ros2Face, StandInHi, int], router: Fleet
) -> None:
    _face, hi, port = setup
    progress: queue.SimpleQueue[Any] = queue.SimpleQueue()
    sdk.ROS2Subscriber(
        f"/{SAY_PROGRESS}", messages.SAY_PROGRESS, progress.put, router_ip="127.0.0.1", router_port=port
    )
    client = _client(port, timeout=TIMEOUT)
    response = client.call(sentence="  bring me the cup ")
    assert response is not None
    assert (response.ok, response.outcome, response.report) == (True, "succeeded", "done: bring me the cup")
    assert hi.sentences.get(timeout=TIMEOUT) == "bring me the cup"
    states = [progress.get(timeout=TIMEOUT).state for _ in range(3)]
    assert states == ["requested", "accepted", "succeeded"]
    counters = _counters(router)
    assert counters["forwarded"] >= 1 and counters["answered"] >= 1


def test_an_answer_of_a_hi_outside_fipa_request_is_dropped_and_counted(
    setup: tuple[Ros2Face, StandInHi, int], router: Fleet
) -> None:
    """a_hi's conversation is followed by the runtime's tracker: a second agree is no answer
    fipa-request allows, so it is neither progress nor the call's end."""
    _face, hi, port = setup
    before = _counters(router).get("dropped.out_of_protocol", 0)
    hi.agree_twice.set()
    try:
        response = _client(port, timeout=TIMEOUT).call(sentence="what are you doing?")
    finally:
        hi.agree_twice.clear()
    assert hi.sentences.get(timeout=TIMEOUT) == "what are you doing?"
    assert response is not None
    assert (response.ok, response.outcome) == (True, "succeeded"), response
    assert _counters(router)["dropped.out_of_protocol"] == before + 1


def test_each_malformed_or_out_of_protocol_call_is_refused_counted_and_the_face_goes_on(
    setup: tuple[Ros2Face, StandInHi, int], router: Fleet
) -> None:
    face, hi, port = setup
    before = _counters(router)
    # a type hash of another type: a Zenoh error reply (no Say response would fit the caller)
    assert (
        _client(port, timeout=TIMEOUT, type_hash=BAD_HASH).call(sentence="pour the jar into the bowl") is None
    )
    client = _client(port, timeout=TIMEOUT)
    from zenoh_ros2_sdk.attachment import Attachment  # the SDK's own encoder of the 33 octets

    attachment = Attachment(sequence_id=7, timestamp_ns=time.time_ns(), gid=bytes(range(16))).to_bytes()
    # a payload that is no CDR of Say_Request: a string said to be 2**31 octets long
    bad_cdr = _raw_call(port, client.keyexpr, b"\x00\x01\x00\x00\xff\xff\xff\x7fpour", attachment)
    assert (bad_cdr.ok, bad_cdr.outcome) == (False, "refused") and "CDR" in bad_cdr.report
    # no attachment
    assert "refused (attachment)" in _raw_call(port, client.keyexpr, b"", None)
    # over the bound: not read
    big = _raw_call(port, client.keyexpr, b"\x00" * 20000, attachment)
    assert (big.ok, big.outcome) == (False, "refused") and "20000 octets" in big.report
    # an empty sentence is no Sentence of L_HC
    assert client.call(sentence="   ").outcome == "refused"
    # a second call while the client's first is open: outside fipa-request's one request
    hi.hold.set()
    first: queue.SimpleQueue[Any] = queue.SimpleQueue()
    client.call_async(first.put, sentence="pour the jar into the bowl")
    assert hi.sentences.get(timeout=TIMEOUT) == "pour the jar into the bowl"
    second = client.call(sentence="what are you doing?")
    assert (second.ok, second.outcome) == (False, "refused") and "one at a time" in second.report
    # a call a_hi never answers expires when the next comes after MAX_CALL_S: the client may call again
    hi.hold.clear()
    real = face.clock
    face.clock = lambda: real() + 2 * MAX_CALL_S
    try:
        retried = client.call(sentence="pour the jar into the bowl")
    finally:
        face.clock = real
    assert retried is not None and retried.ok
    assert first.get(timeout=TIMEOUT) is None  # its error reply
    counters = _counters(router)
    assert counters["expired"] == before.get("expired", 0) + 1
    for reason in ("type_hash", "cdr", "attachment", "too_big", "content", "protocol"):
        assert counters.get(f"refused.{reason}", 0) == before.get(f"refused.{reason}", 0) + 1, reason
    assert "refused" in summary(counters) and "protocol 1" in summary(counters)
    # the face goes on: another client's sentence is answered
    after = _client(port, timeout=TIMEOUT).call(sentence="what is in the bowl?")
    assert after is not None and after.ok and after.report == "done: what is in the bowl?"
    assert face.counters["internal_errors"] == 0


class _Query:
    """A Zenoh query's side the face uses when it answers at once."""

    def __init__(self) -> None:
        self.errors: list[bytes] = []

    def reply_err(self, payload: bytes) -> None:
        self.errors.append(payload)

    def drop(self) -> None:
        pass


def test_snapshots_are_never_queued_and_calls_beyond_the_bound_are_answered_busy() -> None:
    """ag_ex's snapshots replace each other until the face's thread takes the latest; a call
    that finds MAX_WAITING things waiting is answered busy on Zenoh's thread (not started
    here: nothing is taken)."""
    from services.ros2 import face as face_module
    from services.ros2.node import Call

    face = Ros2Face(None, default_spec(), FaceConfig())  # type: ignore[arg-type]  # no session needed
    for n in range(3):
        face._on_state("roco/state/ag_ex", bytes([n]))
    assert face._queue.qsize() == 1 and face.counters["skipped.state"] == 2
    assert face._latest_state() == bytes([2]) and face._latest_state() == b""
    for _ in range(face_module.MAX_WAITING - 1):
        face._enqueue("c1")("k", b"")
    query = _Query()
    face._on_call(Call(query, "h", b"", b"", 0))  # type: ignore[arg-type]
    assert query.errors and b"busy" in query.errors[0] and face.counters["refused.busy"] == 1
    face._enqueue("answer")("k", b"")
    assert face.counters["dropped.waiting"] == 1 and face._queue.qsize() == face_module.MAX_WAITING
