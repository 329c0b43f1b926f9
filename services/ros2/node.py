"""A ROS 2 node on a Zenoh session, in rmw_zenoh's wire format (services/ros2/rmw.py): its
liveliness token, publishers (CDR payloads with the 33-byte attachment) and service servers
(queryables). The manual: docs/ros2.md.

Source: rmw_zenoh's design document, https://github.com/ros2/rmw_zenoh/blob/rolling/docs/design.md
("Graph Cache", "Publishers", "Service Servers"). The node holds only what it declares;
closing it undeclares them all.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh
from rosbags.typesys.store import Typestore

from services.ros2 import rmw
from services.ros2.rmw import Attachment, Endpoint, EntityKind, Node, QoS, RmwError

CDR = "application/cdr"
TOPIC_QOS = QoS(depth=10)
"""The QoS of roco's publishers: rmw_zenoh's defaults but a depth of 10 (rclcpp's usual)."""


def now_ns() -> int:
    """Nanoseconds since the UNIX epoch (the attachment's source timestamp)."""
    return time.time_ns()


class Publisher:
    """One topic's publisher: :meth:`publish` puts a message of ``ros_type`` as CDR with its
    attachment (sequence number from 1, source timestamp, the publisher's GID)."""

    def __init__(self, session: zenoh.Session, store: Typestore, endpoint: Endpoint, ros_type: str) -> None:
        self.endpoint = endpoint
        self.ros_type = ros_type
        self.token_key = rmw.endpoint_token(endpoint)
        self.gid = rmw.gid_of(self.token_key)
        self._store = store
        self._seq = itertools.count(1)
        self._pub = session.declare_publisher(endpoint.key, encoding=CDR)
        self._token = session.liveliness().declare_token(self.token_key)
        self._listeners: list[Any] = []

    def on_matching(self, changed: Callable[[bool], None]) -> bool:
        """Call ``changed`` (on Zenoh's thread) whenever whether a subscriber matches this topic
        changes (Zenoh's matching status: a ROS 2 subscription of rmw_zenoh is a subscriber on
        the same key); returns whether one matches now."""
        self._listeners.append(self._pub.declare_matching_listener(lambda s: changed(s.matching)))
        return bool(getattr(self._pub.matching_status, "matching", False))  # its stub says bool

    def publish(self, msg: Any) -> None:
        """Put ``msg`` (an instance of the store's class of ``ros_type``)."""
        data = bytes(self._store.serialize_cdr(msg, self.ros_type))
        attachment = Attachment(next(self._seq), now_ns(), self.gid).encode()
        self._pub.put(data, attachment=attachment)

    def close(self) -> None:
        for listener in self._listeners:
            listener.undeclare()
        self._token.undeclare()
        self._pub.undeclare()


@dataclass
class Call:
    """One request to a service: the Zenoh ``query`` (answered once, by :meth:`Service.answer`
    or :meth:`Service.fail`), the key's type hash, the attachment octets (``?`` when over 64) and
    the CDR payload."""

    query: zenoh.Query
    type_hash: str
    attachment: bytes
    payload: bytes
    size: int
    """The payload's size; over the service's bound, ``payload`` is empty (not copied)."""


class Service:
    """A service server: a queryable on the service's key with any type hash (complete: it
    answers every request), so that a request of another type reaches it and is refused rather
    than lost; ``on_call`` gets each :class:`Call` on Zenoh's thread and must not block."""

    def __init__(
        self,
        session: zenoh.Session,
        store: Typestore,
        endpoint: Endpoint,
        srv_type: str,
        on_call: Callable[[Call], None],
        max_payload: int,
    ) -> None:
        self.endpoint = endpoint
        self.srv_type = srv_type
        self.token_key = rmw.endpoint_token(endpoint)
        self._store = store
        self._on_call = on_call
        self._max = max_payload
        key = rmw.topic_key(endpoint.node.domain, endpoint.name, endpoint.type_name, "*")
        self._queryable = session.declare_queryable(key, self._take, complete=True)
        self._token = session.liveliness().declare_token(self.token_key)

    def _take(self, query: zenoh.Query) -> None:
        payload, attachment = query.payload, query.attachment
        size = len(payload) if payload is not None else 0
        data = payload.to_bytes() if payload is not None and size <= self._max else b""
        extra = attachment.to_bytes() if attachment is not None and len(attachment) <= 64 else b"?"
        self._on_call(Call(query, str(query.key_expr).rsplit("/", 1)[-1], extra, data, size))

    def decode_request(self, call: Call) -> Any:
        """The request in ``call``. Raises RmwError when it is not the CDR of the request type."""
        try:
            return self._store.deserialize_cdr(call.payload, f"{self.srv_type}_Request")
        except Exception as exc:  # rosbags raises what its decoder meets: struct, index, unicode…
            raise RmwError(
                f"the request is no CDR of {self.srv_type}_Request: {type(exc).__name__}"
            ) from None

    def answer(self, call: Call, response: Any, attachment: Attachment) -> None:
        """Reply ``response`` (the response type's class) to ``call`` with the client's sequence
        number and GID in ``attachment`` and a new source timestamp; the query is then done."""
        data = bytes(self._store.serialize_cdr(response, f"{self.srv_type}_Response"))
        again = Attachment(attachment.sequence, now_ns(), attachment.gid).encode()
        call.query.reply(call.query.key_expr, data, encoding=CDR, attachment=again)
        call.query.drop()

    def fail(self, call: Call, reason: str) -> None:
        """Answer ``call`` with a Zenoh error reply carrying ``reason`` (for a request no
        response of this type can answer: another type's)."""
        call.query.reply_err(reason.encode())
        call.query.drop()

    def close(self) -> None:
        self._token.undeclare()
        self._queryable.undeclare()


class RosNode:
    """ROS 2 node ``name`` in ``namespace`` on ``domain``, over ``session``; types from
    ``store`` (rosbags). Declares its ``NN`` token at once; :meth:`publisher` and
    :meth:`service` add entities (ids from 1, in order)."""

    def __init__(
        self,
        session: zenoh.Session,
        store: Typestore,
        *,
        domain: int = 0,
        namespace: str = "/",
        name: str = "roco",
    ) -> None:
        if not 0 <= domain <= 232:
            raise RmwError(f"domain id {domain}: ROS 2 domains are 0 to 232")
        if namespace != "/":
            rmw.fully_qualified(namespace)  # a namespace is a name: same rules
        self.session = session
        self.store = store
        self.node = Node(domain, str(session.zid()), 0, name, namespace)
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._token = session.liveliness().declare_token(rmw.node_token(self.node))
        self._entities: list[Publisher | Service] = []

    def _endpoint(self, kind: EntityKind, name: str, ros_type: str, qos: QoS) -> Endpoint:
        full = rmw.fully_qualified(name, self.node.namespace)
        with self._lock:
            entity_id = next(self._ids)
        return Endpoint(
            self.node,
            entity_id,
            kind,
            full,
            rmw.dds_type_name(ros_type),
            rmw.type_hash(self.store, ros_type),
            qos,
        )

    def publisher(self, topic: str, ros_type: str, qos: QoS = TOPIC_QOS) -> Publisher:
        """A publisher of ``ros_type`` on ``topic`` (relative names in the node's namespace)."""
        pub = Publisher(
            self.session, self.store, self._endpoint(EntityKind.PUBLISHER, topic, ros_type, qos), ros_type
        )
        self._entities.append(pub)
        return pub

    def service(
        self, name: str, srv_type: str, on_call: Callable[[Call], None], *, max_payload: int = 16384
    ) -> Service:
        """A server of ``srv_type`` (registered in the store: rmw.register_service) on ``name``;
        ``on_call`` as :class:`Service`'s; requests over ``max_payload`` octets are not copied."""
        ep = self._endpoint(EntityKind.SERVICE, name, srv_type, TOPIC_QOS)
        srv = Service(self.session, self.store, ep, srv_type, on_call, max_payload)
        self._entities.append(srv)
        return srv

    def close(self) -> None:
        """Undeclare every entity, then the node's token."""
        for e in reversed(self._entities):
            e.close()
        self._entities.clear()
        self._token.undeclare()
