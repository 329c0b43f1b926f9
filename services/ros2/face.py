"""``roco ros2``'s work: a ROS 2 node ``roco`` on the fleet's own Zenoh (services/ros2/node.py)
that publishes the robot's state and serves a person's sentence to a_hi. The manual:
docs/ros2.md.

Out (only the topics asked for): ``joint_states`` (sensor_msgs/msg/JointState) and ``tf``
(tf2_msgs/msg/TFMessage: the world pose of each link) from ag_ex's snapshots on
``roco/state/ag_ex``, stamped with the simulation's time; ``roco/task_state``
(roco_msgs/msg/TaskState) from a_ta's L_SW informs to a_co on C1; ``head_camera/image_raw``
(sensor_msgs/msg/Image, rgb8) and ``head_camera/camera_info`` (sensor_msgs/msg/CameraInfo) from
ag_ex's images on ``roco/state/ag_ex/camera``, stamped with the robot time of the frame: the face
subscribes there only while a ROS 2 subscriber matches one of the two topics, and ag_ex renders
only while the face subscribes (Zenoh's matching status at both hops).

In: the service ``roco/say`` (roco_msgs/srv/Say). Each call is checked as the gateway checks
HTTP traffic (docs/gateway.md): the key's type hash, the attachment (33 octets), the size, the
CDR, the sentence (at most ``MAX_LINE_CHARS`` characters), one call at a time per client, then
the specification: the caller ``c<client GID in hex>@ros2`` plays x_ros2, which may send a_hi
a fipa-request of a ``Sentence`` in L_HC on C9 and nothing else. A call that fails a check is
answered at once (``ok`` false, ``outcome`` ``refused``, the reason as ``report``; a Zenoh
error reply for another type's hash or a bad attachment) and counted ``refused.<reason>``.
A taken call is put on Zenoh as the caller; a_hi's ``agree`` is published as progress on
``roco/say/progress`` (roco_msgs/msg/SayProgress), as are a_ta's states meanwhile; its final
answer (inform, failure, refuse, not-understood) answers the call.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
import uuid
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import msgspec
import numpy as np
from rosbags.typesys.store import Typestore

from services.ros2 import messages, rmw, state
from services.ros2.node import Call, Publisher, RosNode, Service
from services.ros2.rmw import Attachment, RmwError
from services.runtime import keys
from services.runtime.human import MAX_LINE_CHARS
from services.runtime.log_format import escape_controls
from services.runtime.protocol_state import ConversationError, CrossingTracker, follow
from services.runtime.transport import ZenohTransport
from services.spec.model import MessageKind, SystemSpec, channel_between, interface
from shared.fipa_codec import AgentIdentifier, Communicate, DecodeError, Performative, decode, encode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import LANGUAGES, ContentError, decode_content, encode_content, load_all
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_hc import Sentence, SentenceReport
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, ProtocolViolation
from velma.executor.camera_feed import MAX_FRAME_OCTETS, CameraFrame

ROS2 = "ros2"
"""The face's identity on Zenoh (services/spec_check/acl.py: ROS2) and its callers' platform."""
SAY = "roco/say"
SAY_PROGRESS = "roco/say/progress"
JOINT_STATES, TF, TASK_STATE, CAMERA = "joint_states", "tf", "roco/task_state", "head_camera"
TOPICS = (JOINT_STATES, TF, TASK_STATE, CAMERA)
IMAGE_RAW = state.IMAGE.removeprefix("/")
CAMERA_INFO = state.CAMERA_INFO.removeprefix("/")
"""The camera's two topics (``CAMERA`` asks for both), named as ``roco export`` names them."""
"""What ``roco ros2`` may publish besides the sentence service's progress."""
MAX_REQUEST = 8192
"""The largest request payload read (octets): a sentence of MAX_LINE_CHARS characters fits."""
MAX_OPEN = 64
"""The most calls answered at once; one more is refused ``busy``."""
MAX_WAITING = 1024
"""The most things waiting for the face's thread; a call beyond is answered ``busy`` at once
(an error reply), a communicate dropped and counted ``dropped.waiting``."""
MAX_CALL_S = 3600.0
"""A call a_hi has not answered after this long (s) is dropped when the next call comes: its
caller may call again (a ROS 2 client has long given up), counted ``expired``."""
REFUSE_REASONS: dict[str, str] = {
    "type_hash": "the key's type hash is not roco_msgs/srv/Say's",
    "attachment": "no rmw_zenoh attachment of 33 octets",
    "too_big": f"a request over {MAX_REQUEST} octets",
    "cdr": "the payload is no CDR of roco_msgs/srv/Say_Request",
    "content": f"an empty sentence, or one over {MAX_LINE_CHARS} characters",
    "protocol": "a second call of a client whose first is not answered (one request at a time)",
    "busy": f"over {MAX_OPEN} calls open",
    "not_in_interface": "the specification gives x_ros2 no such request to a_hi",
}
"""Why a call is refused, each counted ``refused.<reason>``."""

log = logging.getLogger(ROS2)


def say_store() -> Typestore:
    """services/ros2/messages.py's type store with roco_msgs/srv/Say registered as a service
    (``Say_Request``, ``Say_Response``, ``Say_Event``: rmw.register_service)."""
    store = messages.typestore()
    if f"{messages.SAY}_Request" not in store.fielddefs:
        request, response = messages.SAY_SRV.split("---\n")
        rmw.register_service(store, messages.SAY, request, response)
    return store


class _Refused(Exception):
    """A call that fails a check: ``reason`` (a key of :data:`REFUSE_REASONS`), the text, and
    its attachment when it has one (then answered with a response, else an error reply)."""

    def __init__(self, reason: str, text: str, attachment: Attachment | None = None) -> None:
        super().__init__(text)
        self.reason = reason
        self.attachment = attachment


def _request_kind(spec: SystemSpec, role: str) -> MessageKind | None:
    """What ``role`` may send a_hi as a fipa-request ``request`` carrying a Sentence, or None."""
    for k in interface(spec, role).sends:
        if (k.receiver, k.performative, k.protocol) == ("a_hi", "request", "fipa-request"):
            return k if not k.contents or "Sentence" in k.contents else None
    return None


class _Glance(msgspec.Struct, frozen=True):
    """What the face reads of ag_ex's RobotSnapshot (velma/executor/state.py)."""

    sim_time: float
    joints: dict[str, float]
    links: dict[str, Pose] = {}


@dataclass(frozen=True)
class FaceConfig:
    """``domain`` (ROS_DOMAIN_ID), the node's ``namespace``, the ``topics`` to publish (of
    :data:`TOPICS`) and whether to serve ``roco/say`` (``say``)."""

    domain: int = 0
    namespace: str = "/"
    topics: frozenset[str] = frozenset()
    say: bool = True


@dataclass
class _Open:
    call: Call
    attachment: Attachment
    sentence: str
    caller: str
    started: float
    command_id: str = ""
    conversation: CrossingTracker = field(default_factory=lambda: _requested("fipa-request"))
    """The call's conversation with a_hi, followed through its protocol (the face initiates)."""


def _requested(protocol: str) -> CrossingTracker:
    tracker = CrossingTracker(protocol, local_role=INITIATOR)
    tracker.step(INITIATOR, Performative.REQUEST)
    return tracker


class Ros2Face:
    """The ROS 2 face of one fleet: ``transport`` authenticated as :data:`ROS2`, ``spec`` the
    fleet's specification. :meth:`bind` declares everything, :meth:`start` handles what
    arrives on a thread of its own, :meth:`stop` undeclares. ``counters`` as ``roco status``
    shows them."""

    def __init__(self, transport: ZenohTransport, spec: SystemSpec, config: FaceConfig) -> None:
        load_all()
        unknown = set(config.topics) - set(TOPICS)
        if unknown:
            raise ValueError(f"no such topic of roco ros2: {', '.join(sorted(unknown))}")
        self.transport = transport
        self.spec = spec
        self.config = config
        self.counters: Counter[str] = Counter()
        self.store = say_store()
        self.say_hash = rmw.type_hash(self.store, messages.SAY)
        self.role = next((e.name for e in spec.externals if e.platform == ROS2), "")
        self._queue: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._open: dict[str, _Open] = {}
        self.clock: Callable[[], float] = time.monotonic
        """The face's clock for :data:`MAX_CALL_S` (tests set it)."""
        self._callers: set[str] = set()
        self._state: bytes | None = None
        """ag_ex's latest snapshot not yet published: a newer one replaces it (never queued)."""
        self._image: bytes | None = None
        """ag_ex's latest camera frame not yet published (as ``_state``)."""
        self._camera_sub: Any = None
        self._matching = {IMAGE_RAW: False, CAMERA_INFO: False}
        """Whether a ROS 2 subscriber matches each camera topic (the face's thread's)."""
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.node: RosNode | None = None
        self._pubs: dict[str, Publisher] = {}
        self._say: Service | None = None

    # ---- life ----------------------------------------------------------------------------
    def bind(self) -> None:
        """Declare the node, its publishers and service; subscribe to what feeds them; hold
        ``roco/alive/ros2``. Raises RmwError for a bad namespace or domain."""
        cfg = self.config
        node = self.node = RosNode(
            self.transport.session, self.store, domain=cfg.domain, namespace=cfg.namespace
        )
        kinds = {JOINT_STATES: "sensor_msgs/msg/JointState", TF: "tf2_msgs/msg/TFMessage"}
        for topic in (JOINT_STATES, TF):
            if topic in cfg.topics:
                self._pubs[topic] = node.publisher(topic, kinds[topic])
        if cfg.topics & {JOINT_STATES, TF}:
            self.transport.subscribe(keys.state_key("ag_ex"), self._on_state)
        self._bind_camera(node)
        if TASK_STATE in cfg.topics:
            self._pubs[TASK_STATE] = node.publisher(TASK_STATE, messages.TASK_STATE)
            self.transport.subscribe(keys.fipa_key("C1", "a_ta", "a_co"), self._enqueue("c1"))
        if cfg.say and self.role:
            self._pubs[SAY_PROGRESS] = node.publisher(SAY_PROGRESS, messages.SAY_PROGRESS)
            self._say = node.service(SAY, messages.SAY, self._on_call, max_payload=MAX_REQUEST)
            for ch in self.spec.channels:
                if self.role in ch.ends:
                    agent = ch.ends[0] if ch.ends[1] == self.role else ch.ends[1]
                    hears = f"{keys.FIPA_PREFIX}{ch.name}/{keys.key_chunk(agent)}/$*@{ROS2}"
                    self.transport.subscribe(hears, self._enqueue("answer"))
        self.transport.subscribe(keys.COUNTERS_ASK, self._enqueue("ask"))
        self.transport.announce(keys.alive_key(ROS2))

    def _bind_camera(self, node: RosNode) -> None:
        """The camera's publishers; whether a subscriber matches each goes to the face's thread,
        which subscribes to ag_ex's images while one does (never declared on Zenoh's thread).
        Nothing unless the camera was asked for."""
        if CAMERA not in self.config.topics:
            return
        types = {IMAGE_RAW: state.IMAGE_TYPE, CAMERA_INFO: state.CAMERA_INFO_TYPE}
        for topic, ros_type in types.items():
            pub = self._pubs[topic] = node.publisher(topic, ros_type)

            def changed(matching: bool, topic: str = topic) -> None:
                self._queue.put(("matching", (topic, matching)))

            changed(pub.on_matching(changed))

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name=ROS2, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread, then undeclare the node (open calls get no answer)."""
        self._queue.put(("stop", None))
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        if self._camera_sub is not None:
            self._camera_sub.undeclare()
            self._camera_sub = None
        if self.node is not None:
            self.node.close()

    def _enqueue(self, kind: str) -> Callable[[str, bytes], None]:
        def put(key: str, payload: bytes) -> None:
            if self._queue.qsize() >= MAX_WAITING:
                self.count("dropped.waiting")
                return
            self._queue.put((kind, (key, payload)))

        return put

    def _on_state(self, key: str, payload: bytes) -> None:
        with self._lock:
            waiting, self._state = self._state is not None, payload
        if waiting:
            self.count("skipped.state")
        else:
            self._queue.put(("state", None))

    def _on_image(self, sample: Any) -> None:
        """Zenoh's thread: keep the latest frame (too big: dropped unread)."""
        if len(sample.payload) > MAX_FRAME_OCTETS:
            self.count("dropped.camera")
            return
        with self._lock:
            waiting, self._image = self._image is not None, sample.payload.to_bytes()
        if waiting:
            self.count("skipped.camera")
        else:
            self._queue.put(("image", None))

    def _on_call(self, call: Call) -> None:
        """Zenoh's thread: enqueue only; over :data:`MAX_WAITING` waiting, answer busy."""
        if self._queue.qsize() >= MAX_WAITING:
            self.count("refused")
            self.count("refused.busy")
            call.query.reply_err(b"refused (busy): too many calls waiting")
            call.query.drop()
            return
        self._queue.put(("call", call))

    def count(self, name: str) -> None:
        with self._lock:
            self.counters[name] += 1

    def _run(self) -> None:
        handlers: dict[str, Callable[[Any], None]] = {
            "call": self._take_call,
            "answer": lambda item: self._take_answer(*item),
            "state": lambda item: self._take_state(self._latest_state()),
            "c1": lambda item: self._take_c1(item[1]),
            "matching": lambda item: self._take_matching(*item),
            "image": lambda item: self._take_image(self._latest_image()),
            "ask": lambda item: self._report_counters(),
        }
        while True:
            kind, item = self._queue.get()
            if kind == "stop":
                return
            try:
                handlers[kind](item)
            except Exception:  # nothing one message does stops the face
                self.count("internal_errors")
                log.exception("handling %s raised", kind)

    def _report_counters(self) -> None:
        with self._lock:
            counters = dict(self.counters)
        report = {
            "agent": ROS2,
            "time": time.time(),
            "session": self.transport.session_id,
            "counters": counters,
        }
        self.transport.publish(keys.counters_key(ROS2), msgspec.json.encode(report))

    # ---- out: the robot's state ------------------------------------------------------------
    def _stamp(self, t: float) -> Any:
        time_cls = self.store.types["builtin_interfaces/msg/Time"]
        sec = int(t)
        return time_cls(sec=sec, nanosec=round((t - sec) * 1e9) % 1_000_000_000)

    def _header(self, t: float, frame: str) -> Any:
        return self.store.types["std_msgs/msg/Header"](stamp=self._stamp(t), frame_id=frame)

    def _latest_state(self) -> bytes:
        with self._lock:
            payload, self._state = self._state or b"", None
        return payload

    def _take_state(self, payload: bytes) -> None:
        try:
            glance = msgspec.msgpack.decode(payload, type=_Glance)
        except (msgspec.DecodeError, msgspec.ValidationError):
            self.count("dropped.state")
            return
        types = self.store.types
        if (pub := self._pubs.get(JOINT_STATES)) is not None:
            empty = np.zeros(0, dtype=np.float64)
            pub.publish(
                types["sensor_msgs/msg/JointState"](
                    header=self._header(glance.sim_time, ""),
                    name=list(glance.joints),
                    position=np.fromiter(glance.joints.values(), dtype=np.float64),
                    velocity=empty,
                    effort=empty,
                )
            )
            self.count("published.joint_states")
        if (pub := self._pubs.get(TF)) is not None and glance.links:
            pub.publish(
                types["tf2_msgs/msg/TFMessage"](
                    transforms=[self._transform(glance, b, p) for b, p in glance.links.items()]
                )
            )
            self.count("published.tf")

    def _transform(self, glance: _Glance, body: str, pose: Pose) -> Any:
        t = self.store.types
        w, x, y, z = pose.orientation
        return t["geometry_msgs/msg/TransformStamped"](
            header=self._header(glance.sim_time, pose.frame),
            child_frame_id=body,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](
                    x=pose.position[0], y=pose.position[1], z=pose.position[2]
                ),
                rotation=t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
            ),
        )

    # ---- out: the head camera -------------------------------------------------------------
    def _take_matching(self, topic: str, matching: bool) -> None:
        """Subscribe to ag_ex's images while a ROS 2 subscriber matches a camera topic."""
        self._matching[topic] = matching
        wanted = any(self._matching.values())
        if wanted and self._camera_sub is None:
            key = keys.camera_key("ag_ex")
            self._camera_sub = self.transport.session.declare_subscriber(key, self._on_image)
            log.info("a ROS 2 subscriber of the camera: subscribed to %s", key)
        elif not wanted and self._camera_sub is not None:
            self._camera_sub.undeclare()
            self._camera_sub = None
            with self._lock:
                self._image = None
            log.info("no ROS 2 subscriber of the camera any more: unsubscribed")

    def _latest_image(self) -> bytes:
        with self._lock:
            payload, self._image = self._image or b"", None
        return payload

    def _take_image(self, payload: bytes) -> None:
        try:
            frame = msgspec.msgpack.decode(payload, type=CameraFrame)
        except (msgspec.DecodeError, msgspec.ValidationError):
            self.count("dropped.camera")
            return
        w, h = frame.width, frame.height
        if frame.encoding != "rgb8" or w <= 0 or h <= 0 or len(frame.data) != 3 * w * h:
            self.count("dropped.camera")
            return
        header = self._header(frame.stamp, state.OPTICAL_FRAME)
        image = self.store.types[state.IMAGE_TYPE](
            header=header,
            height=h,
            width=w,
            encoding="rgb8",
            is_bigendian=0,
            step=3 * w,
            data=np.frombuffer(frame.data, dtype=np.uint8),
        )
        self._pubs[IMAGE_RAW].publish(image)
        self.count("published.image_raw")
        k = ((frame.fx, 0.0, frame.cx), (0.0, frame.fy, frame.cy), (0.0, 0.0, 1.0))
        self._pubs[CAMERA_INFO].publish(state.camera_info(self.store, header, w, h, k))
        self.count("published.camera_info")

    def _statuses(self, payload: bytes) -> list[SWStatus]:
        """a_ta's L_SW informs in a C1 payload (a batch or one communicate)."""
        out = []
        for item in unpack(payload):
            try:
                msg = decode(item)
                status = decode_content(msg.language, msg.content) if msg.content else None
            except (DecodeError, ContentError):
                self.count("dropped.c1")
                continue
            if isinstance(status, SWStatus) and msg.performative is Performative.INFORM:
                out.append(status)
        return out

    def _take_c1(self, payload: bytes) -> None:
        pub = self._pubs.get(TASK_STATE)
        for status in self._statuses(payload):
            step, state, detail = status.step or "", status.state.value, status.reason or ""
            if pub is not None:
                pub.publish(
                    self.store.types[messages.TASK_STATE](
                        stamp=self._stamp(time.time()),
                        command_id=status.plan_id,
                        text="",
                        state=state,
                        step=step,
                        path=f"{state} {step}".strip(),
                        detail=detail,
                    )
                )
                self.count("published.task_state")
            for opened in list(self._open.values()):
                self._progress(opened, state, step, detail)

    def _progress(self, opened: _Open, state: str, step: str = "", detail: str = "") -> None:
        if (pub := self._pubs.get(SAY_PROGRESS)) is None:
            return
        pub.publish(
            self.store.types[messages.SAY_PROGRESS](
                stamp=self._stamp(time.time()),
                sentence=opened.sentence,
                command_id=opened.command_id,
                state=state,
                step=step,
                detail=detail,
            )
        )
        self.count("published.say_progress")

    # ---- in: calls of roco/say ------------------------------------------------------------
    def _refuse(self, call: Call, reason: str, text: str, attachment: Attachment | None) -> None:
        text = escape_controls(text[:500])
        self.count("refused")
        self.count(f"refused.{reason}")
        log.warning("refused a call of %s: %s", SAY, text)
        assert self._say is not None
        if attachment is None:
            self._say.fail(call, f"refused ({reason}): {text}")
            return
        response = self.store.types[f"{messages.SAY}_Response"](ok=False, outcome="refused", report=text)
        self._say.answer(call, response, attachment)

    def _checked(self, call: Call) -> tuple[Attachment, str, str]:
        """The attachment, sentence and caller name of ``call``; :class:`_Refused` when it fails
        a check of the module docstring (in its order)."""
        if call.type_hash != self.say_hash:
            raise _Refused("type_hash", f"type hash {call.type_hash[:80]} is not {messages.SAY}'s")
        try:
            attachment = Attachment.decode(call.attachment)
        except RmwError as exc:
            raise _Refused("attachment", str(exc)) from None
        if call.size > MAX_REQUEST:
            raise _Refused("too_big", f"{call.size} octets (at most {MAX_REQUEST})", attachment)
        assert self._say is not None
        try:
            request = self._say.decode_request(call)
        except RmwError as exc:
            raise _Refused("cdr", str(exc), attachment) from None
        sentence = str(request.sentence).strip()
        if not sentence or len(sentence) > MAX_LINE_CHARS:
            raise _Refused("content", f"a sentence of 1 to {MAX_LINE_CHARS} characters", attachment)
        caller = f"c{attachment.gid.hex()}@{ROS2}"
        if caller in self._callers:
            raise _Refused("protocol", f"{caller} has a call not yet answered (one at a time)", attachment)
        if len(self._open) >= MAX_OPEN:
            raise _Refused("busy", f"{len(self._open)} calls open (at most {MAX_OPEN})", attachment)
        return attachment, sentence, caller

    def _expire(self) -> None:
        """Drop the calls open longer than :data:`MAX_CALL_S` (answered with an error reply)."""
        now = self.clock()
        for conversation, opened in list(self._open.items()):
            if now - opened.started > MAX_CALL_S:
                del self._open[conversation]
                self._callers.discard(opened.caller)
                self.count("expired")
                assert self._say is not None
                self._say.fail(opened.call, f"no answer of a_hi within {MAX_CALL_S:.0f} s")

    def _take_call(self, call: Call) -> None:
        self.count("received")
        self._expire()
        try:
            attachment, sentence, caller = self._checked(call)
            try:
                channel, communicate = self._admit(caller, sentence)
            except LookupError as exc:
                raise _Refused("not_in_interface", str(exc), attachment) from None
        except _Refused as refused:
            self._refuse(call, refused.reason, str(refused), refused.attachment)
            return
        self.transport.publish(keys.fipa_key(channel, caller, "a_hi"), encode(communicate))
        assert communicate.conversation_id is not None
        opened = _Open(call, attachment, sentence, caller, started=self.clock())
        self._open[communicate.conversation_id] = opened
        self._callers.add(caller)
        self.count("forwarded")
        log.info(
            "%s → a_hi on %s: %r (conversation %s)",
            caller,
            channel,
            sentence[:200],
            communicate.conversation_id,
        )
        self._progress(opened, "requested")

    def _admit(self, caller: str, sentence: str) -> tuple[str, Communicate]:
        """The channel and the fipa-request of ``sentence`` from ``caller`` to a_hi, as the
        specification gives the caller's role; LookupError when it gives none."""
        role = self.spec.role_of(caller)
        channel = channel_between(self.spec, role, "a_hi") if role == self.role else None
        kind = _request_kind(self.spec, role) if channel is not None else None
        language, content = encode_content(Sentence(text=sentence))
        if channel is None or kind is None or (kind.languages and language not in kind.languages):
            raise LookupError(f"{caller} ({role}) may not request a Sentence in {language} of a_hi")
        conversation = f"ros2-{uuid.uuid4().hex[:16]}"
        return channel.name, Communicate(
            performative=Performative.REQUEST,
            sender=AgentIdentifier(caller),
            receiver=(AgentIdentifier("a_hi"),),
            content=content,
            language=language,
            encoding="msgpack",
            ontology=LANGUAGES[language].ontology,
            protocol="fipa-request",
            conversation_id=conversation,
            reply_with=conversation,
        )

    def _take_answer(self, key: str, payload: bytes) -> None:
        for item in unpack(payload):
            try:
                msg = decode(item)
            except DecodeError:
                self.count("dropped.malformed")
                continue
            opened = self._open.get(msg.conversation_id or "")
            if opened is None:
                self.count("dropped.no_call")
                continue
            try:  # a_hi's answer as its protocol allows it (a not-understood ends it), or not at all
                _, outcome = follow(
                    opened.conversation,
                    "fipa-request",
                    PARTICIPANT,
                    msg.performative,
                    local_role=INITIATOR,
                    in_reply_to=msg.in_reply_to,
                )
            except (ProtocolViolation, ConversationError):
                outcome = None
            if outcome not in ("step", "crossing", "aborted"):
                self.count("dropped.out_of_protocol")
                continue
            report = self._report(msg)
            if not opened.conversation.is_finished:
                self._progress(opened, report.kind, detail=report.text)
                continue
            ok = msg.performative is Performative.INFORM  # fipa-request's one success
            del self._open[msg.conversation_id or ""]
            self._callers.discard(opened.caller)
            response = self.store.types[f"{messages.SAY}_Response"](
                ok=ok, outcome=report.kind, report=report.text
            )
            self._progress(
                opened, report.kind, detail=report.text
            )  # before: the caller may stop on the answer
            assert self._say is not None
            self._say.answer(opened.call, response, opened.attachment)
            self.count("answered")

    def _report(self, msg: Communicate) -> SentenceReport:
        if msg.performative is Performative.NOT_UNDERSTOOD:
            return SentenceReport(kind="not-understood", text=msg.content.decode("utf-8", "replace")[:2000])
        try:
            term = decode_content(msg.language, msg.content)
        except ContentError:
            term = None
        if isinstance(term, SentenceReport):
            return term
        return SentenceReport(kind=msg.performative.value, text="")


def summary(counters: dict[str, int]) -> str:
    """The face's counters in one line (``roco status``): ``received 3, forwarded 1, refused 2
    (cdr 1, type_hash 1), answered 1, published 250``; the last parts (published, dropped,
    expired, internal_errors) only when not 0."""

    def total(prefix: str) -> int:
        return sum(v for k, v in counters.items() if k.startswith(prefix))

    refused = sorted(
        (k.removeprefix("refused."), v) for k, v in counters.items() if k.startswith("refused.") and v
    )
    detail = " (" + ", ".join(f"{k} {v}" for k, v in refused) + ")" if refused else ""
    line = [f"{n} {counters.get(n, 0)}" for n in ("received", "forwarded")]
    line += [f"refused {counters.get('refused', 0)}{detail}", f"answered {counters.get('answered', 0)}"]
    extra = {
        "published": total("published."),
        "dropped": total("dropped."),
        "expired": total("expired"),
        "internal_errors": total("internal_errors"),
    }
    return ", ".join(line + [f"{k} {v}" for k, v in extra.items() if v])
