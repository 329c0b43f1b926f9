"""rmw_zenoh's wire format as pure functions: data key expressions, liveliness tokens, QoS
strings, the 33-byte attachment, GIDs and RIHS01 type hashes.

Source: rmw_zenoh's design document (Jazzy and later),
https://github.com/ros2/rmw_zenoh/blob/rolling/docs/design.md: "Topic and Service name
mapping to Zenoh key expressions", "Graph Cache", "Publishers", "Service Clients", "Service
Servers"; and its
``qos_to_keyexpr`` (liveliness_utils.cpp) with the defaults of qos.cpp; type hashes per REP-2011
(RIHS01), computed by rosbags' ``Typestore.hash_rihs01``. Nothing here opens a session.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass
from enum import IntEnum, StrEnum
from typing import Any

from rosbags.typesys.store import Typestore

ADMIN_SPACE = "@ros2_lv"
"""The first chunk of every liveliness token (a Zenoh hermetic namespace)."""
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE
"""Sequence number (int64 LE), source timestamp (ns since the UNIX epoch, int64 LE), the GID's
length (one octet, 16) and the GID: 33 octets."""
MAX_NAME = 255
"""The longest topic, service, node or namespace name accepted (REP: names are short)."""


class RmwError(ValueError):
    """Input that is not in rmw_zenoh's format; the message is one line."""


class EntityKind(StrEnum):
    """The ``<entity_kind>`` chunk of a liveliness token."""

    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"
    SERVICE = "SS"
    CLIENT = "SC"


class Reliability(IntEnum):
    """rmw_qos_reliability_policy_e."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class Durability(IntEnum):
    """rmw_qos_durability_policy_e."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class History(IntEnum):
    """rmw_qos_history_policy_e."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


class Liveliness(IntEnum):
    """rmw_qos_liveliness_policy_e."""

    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3


INFINITE = (9223372036, 854775807)
"""RMW_DURATION_INFINITE as (s, ns)."""


@dataclass(frozen=True)
class QoS:
    """A QoS profile as rmw_zenoh writes it in a token; durations are (s, ns)."""

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 42
    deadline: tuple[int, int] = INFINITE
    lifespan: tuple[int, int] = INFINITE
    liveliness: Liveliness = Liveliness.AUTOMATIC
    lease: tuple[int, int] = INFINITE


DEFAULT_QOS = QoS()
"""rmw_zenoh's defaults (qos.cpp): the fields a QoS string leaves empty."""


def qos_string(qos: QoS) -> str:
    """``<rel>:<dur>:<hist>,<depth>:<dl s>,<dl ns>:<ls s>,<ls ns>:<liv>,<lease s>,<lease ns>``,
    each field empty when it equals :data:`DEFAULT_QOS` (``::,10:,:,:,,`` for depth 10)."""
    d = DEFAULT_QOS

    def f(value: Any, default: Any) -> str:
        return "" if value == default else str(int(value))

    return (
        f"{f(qos.reliability, d.reliability)}:{f(qos.durability, d.durability)}:"
        f"{f(qos.history, d.history)},{f(qos.depth, d.depth)}:"
        f"{f(qos.deadline[0], d.deadline[0])},{f(qos.deadline[1], d.deadline[1])}:"
        f"{f(qos.lifespan[0], d.lifespan[0])},{f(qos.lifespan[1], d.lifespan[1])}:"
        f"{f(qos.liveliness, d.liveliness)},{f(qos.lease[0], d.lease[0])},{f(qos.lease[1], d.lease[1])}"
    )


def _number(text: str, default: int, what: str) -> int:
    if text == "":
        return default
    if not text.isdigit() or len(text) > 19:
        raise RmwError(f"QoS {what} {text[:20]!r} is no number")
    return int(text)


def parse_qos(text: str) -> QoS:
    """The QoS of a token's last chunk. Raises RmwError when it has not 6 fields (history and
    deadline 2 parts, liveliness 3), or a field is no number or no known policy."""
    if len(text) > 200:
        raise RmwError("QoS string over 200 characters")
    parts = text.split(":")
    if len(parts) != 6:
        raise RmwError(f"QoS {text[:60]!r}: {len(parts)} fields, not 6")
    hist, dl, ls, lv = (p.split(",") for p in parts[2:])
    if len(hist) != 2 or len(dl) != 2 or len(ls) != 2 or len(lv) != 3:
        raise RmwError(f"QoS {text[:60]!r}: a field has the wrong number of parts")
    d = DEFAULT_QOS
    try:
        return QoS(
            reliability=Reliability(_number(parts[0], d.reliability, "reliability")),
            durability=Durability(_number(parts[1], d.durability, "durability")),
            history=History(_number(hist[0], d.history, "history")),
            depth=_number(hist[1], d.depth, "depth"),
            deadline=(_number(dl[0], d.deadline[0], "deadline"), _number(dl[1], d.deadline[1], "deadline")),
            lifespan=(_number(ls[0], d.lifespan[0], "lifespan"), _number(ls[1], d.lifespan[1], "lifespan")),
            liveliness=Liveliness(_number(lv[0], d.liveliness, "liveliness")),
            lease=(_number(lv[1], d.lease[0], "lease"), _number(lv[2], d.lease[1], "lease")),
        )
    except ValueError as exc:
        if isinstance(exc, RmwError):
            raise
        raise RmwError(f"QoS {text[:60]!r}: {exc}") from None


def mangle(name: str) -> str:
    """A name in one key chunk: each ``/`` as ``%`` (``/chatter`` → ``%chatter``); an empty
    name (or ``/``) is ``%``."""
    return name.replace("/", "%") if name not in ("", "/") else "%"


def demangle(chunk: str) -> str:
    """:func:`mangle` reversed (``%`` → ``/``)."""
    return chunk.replace("%", "/")


def dds_type_name(ros_type: str) -> str:
    """``std_msgs/msg/String`` → ``std_msgs::msg::dds_::String_`` (also ``srv``). Raises
    RmwError for a name not ``package/msg|srv/Name``."""
    parts = ros_type.split("/")
    if len(parts) != 3 or parts[1] not in ("msg", "srv") or not all(p.isidentifier() for p in parts):
        raise RmwError(f"type {ros_type[:80]!r} is not package/msg/Name or package/srv/Name")
    return f"{parts[0]}::{parts[1]}::dds_::{parts[2]}_"


def fully_qualified(name: str, namespace: str = "/") -> str:
    """The fully qualified name of topic or service ``name`` in ``namespace`` (design.ros2.org,
    "Topic and Service Names"): ``chatter`` in ``/robot1`` → ``/robot1/chatter``; a name
    starting with ``/`` stays. Raises RmwError for an empty or over-long name, ``//`` or
    a character other than letters, digits, ``_`` and ``/``."""
    full = name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"
    bare = full.replace("/", "").replace("_", "")
    if (
        not name
        or len(full) > MAX_NAME
        or "//" in full
        or full.endswith("/")
        or not (bare.isalnum() and bare.isascii())
    ):
        raise RmwError(f"name {full[:80]!r} is no ROS 2 topic or service name")
    return full


def topic_key(domain: int, name: str, type_name: str, type_hash: str) -> str:
    """``<domain_id>/<fully_qualified_name without leading slash>/<DDS type>/<type hash>``:
    the key a topic's samples (or a service's queries) travel on."""
    return f"{domain}/{name.strip('/')}/{type_name}/{type_hash}"


@dataclass(frozen=True)
class Node:
    """A ROS 2 node as its tokens name it: domain id, Zenoh session id (hex), node id within
    the session, namespace (``/`` for none), node name and SROS enclave (``/`` for none)."""

    domain: int
    session_id: str
    node_id: int
    name: str
    namespace: str = "/"
    enclave: str = "/"


@dataclass(frozen=True)
class Endpoint:
    """A publisher, subscription, service server or client of ``node``: ``name`` is the fully
    qualified topic or service name, ``type_name`` the DDS type (:func:`dds_type_name`)."""

    node: Node
    entity_id: int
    kind: EntityKind
    name: str
    type_name: str
    type_hash: str
    qos: QoS = DEFAULT_QOS

    @property
    def key(self) -> str:
        """The data key expression (:func:`topic_key`)."""
        return topic_key(self.node.domain, self.name, self.type_name, self.type_hash)


def _node_chunks(node: Node, entity_id: int, kind: EntityKind) -> list[str]:
    return [
        ADMIN_SPACE,
        str(node.domain),
        node.session_id,
        str(node.node_id),
        str(entity_id),
        kind.value,
        mangle(node.enclave),
        mangle(node.namespace),
        node.name,
    ]


def node_token(node: Node) -> str:
    """``@ros2_lv/<domain>/<session>/<node_id>/<node_id>/NN/<enclave>/<namespace>/<name>``."""
    return "/".join(_node_chunks(node, node.node_id, EntityKind.NODE))


def endpoint_token(ep: Endpoint) -> str:
    """The node's chunks with the entity's id and kind, then ``<mangled name>/<DDS type>/<type
    hash>/<QoS string>``."""
    chunks = _node_chunks(ep.node, ep.entity_id, ep.kind)
    return "/".join([*chunks, mangle(ep.name), ep.type_name, ep.type_hash, qos_string(ep.qos)])


def _token_chunks(token: str) -> list[str]:
    """The chunks of a token: RmwError unless 9 or 13, none empty, the first the admin space,
    the ids numbers."""
    if len(token) > 4 * MAX_NAME + 400:
        raise RmwError("liveliness token over its longest possible length")
    c = token.split("/")
    if c[0] != ADMIN_SPACE or len(c) not in (9, 13) or not all(c):
        raise RmwError(f"{token[:80]!r} is no rmw_zenoh liveliness token")
    if not all(c[i].isdigit() for i in (1, 3, 4)):
        raise RmwError(f"{token[:80]!r}: domain, node and entity ids must be numbers")
    return c


def parse_token(token: str) -> Node | Endpoint:
    """The node or endpoint a liveliness token names. Raises RmwError when it is not one:
    another admin space, a kind not NN/MP/MS/SS/SC, a wrong number of chunks, ids that are
    no numbers, or a bad QoS string."""
    c = _token_chunks(token)
    try:
        kind = EntityKind(c[5])
    except ValueError:
        raise RmwError(f"{token[:80]!r}: unknown entity kind {c[5][:4]!r}") from None
    node = Node(int(c[1]), c[2], int(c[3]), c[8], demangle(c[7]), demangle(c[6]))
    if kind is EntityKind.NODE:
        if len(c) != 9:
            raise RmwError(f"{token[:80]!r}: a node's token has 9 chunks")
        return node
    if len(c) != 13:
        raise RmwError(f"{token[:80]!r}: an endpoint's token has 13 chunks")
    return Endpoint(node, int(c[4]), kind, demangle(c[9]), c[10], c[11], parse_qos(c[12]))


def gid_of(token: str) -> bytes:
    """A 16-octet GID for the entity of ``token``: its BLAKE2b-128 (rmw_zenoh hashes the token
    too, with XXH3-128; a GID is opaque to every other entity)."""
    return hashlib.blake2b(token.encode(), digest_size=GID_SIZE).digest()


@dataclass(frozen=True)
class Attachment:
    """The attachment of a sample, query or reply: ``sequence`` (int64), ``timestamp_ns``
    (int64, ns since the UNIX epoch) and the publisher's or client's 16-octet ``gid``."""

    sequence: int
    timestamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        """The 33 octets (:data:`ATTACHMENT_SIZE`). Raises RmwError for a GID not 16 octets
        or a number outside int64."""
        if len(self.gid) != GID_SIZE:
            raise RmwError(f"a GID has {GID_SIZE} octets, not {len(self.gid)}")
        try:
            return struct.pack("<qqB", self.sequence, self.timestamp_ns, GID_SIZE) + self.gid
        except struct.error as exc:
            raise RmwError(f"attachment: {exc}") from None

    @classmethod
    def decode(cls, data: bytes) -> Attachment:
        """The attachment in ``data``. Raises RmwError unless it is 33 octets with a GID length
        of 16."""
        if len(data) != ATTACHMENT_SIZE:
            raise RmwError(f"an attachment has {ATTACHMENT_SIZE} octets, not {len(data)}")
        sequence, timestamp, length = struct.unpack_from("<qqB", data)
        if length != GID_SIZE:
            raise RmwError(f"attachment GID length {length}, not {GID_SIZE}")
        return cls(sequence, timestamp, bytes(data[17:]))


# ---- type hashes (REP-2011) -----------------------------------------------------------------
_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"


def _srv_names(obj: Any) -> Any:
    """rosbags files ``pkg/srv/X`` types as ``pkg/srv/msg/X``; the hash names them ``pkg/srv/X``."""
    if isinstance(obj, str):
        return obj.replace("/srv/msg/", "/srv/")
    if isinstance(obj, (tuple, list)):
        return type(obj)(_srv_names(x) for x in obj)
    return obj


def register_service(store: Typestore, srv_type: str, request: str, response: str) -> None:
    """Register service ``srv_type`` (``pkg/srv/Name``) with ``request`` and ``response``
    definitions (.msg text) in ``store``: ``Name_Request``, ``Name_Response``, ``Name_Event``
    and the service itself (request_message, response_message, event_message), as rosidl
    describes a service for its hash (REP-2011). Raises RmwError for a bad ``srv_type``."""
    from rosbags.typesys import get_types_from_msg

    dds_type_name(srv_type)
    if "/srv/" not in srv_type:
        raise RmwError(f"{srv_type!r} is no service type")
    req, res, evt = (f"{srv_type}_{s}" for s in ("Request", "Response", "Event"))
    types: dict[str, Any] = {}
    types.update(get_types_from_msg(request, req))
    types.update(get_types_from_msg(response, res))
    types.update(get_types_from_msg(f"{_EVENT_INFO} info\n{req}[<=1] request\n{res}[<=1] response\n", evt))
    service = f"{req} request_message\n{res} response_message\n{evt} event_message\n"
    types.update(get_types_from_msg(service, srv_type))
    store.register({_srv_names(k): _srv_names(v) for k, v in types.items()})


def type_hash(store: Typestore, ros_type: str) -> str:
    """The RIHS01 hash of message or service ``ros_type`` registered in ``store``
    (``RIHS01_<64 hex>``). A .msg ``char`` is IDL ``uint8`` (ServiceEventInfo's client_gid),
    which rosbags would hash as a char. Raises KeyError for a type ``store`` lacks."""
    consts, fields = store.fielddefs.get(_EVENT_INFO, ([], []))
    patched = [(n, _char_as_uint8(d)) for n, d in fields]
    if patched != fields:
        store.fielddefs[_EVENT_INFO] = (consts, patched)
    return store.hash_rihs01(ros_type)


def _char_as_uint8(desc: Any) -> Any:
    if isinstance(desc, tuple) and desc and desc == ("char", 0):
        return ("uint8", 0)
    if isinstance(desc, tuple):
        return tuple(_char_as_uint8(x) for x in desc)
    return desc
