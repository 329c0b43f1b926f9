"""services/ros2/rmw.py against rmw_zenoh's documented examples.

Golden data: rmw_zenoh's design document (Jazzy and later),
https://github.com/ros2/rmw_zenoh/blob/rolling/docs/design.md, sections "Topic and
Service name mapping to Zenoh key expressions" (data keys), "Graph Cache" (liveliness tokens
of the demo_nodes_cpp listener, talker, add_two_ints_server and add_two_ints_client, QoS strings included),
"Publishers"/"Service Clients"/"Service Servers" (the attachment layout). Type hashes: the
RIHS01 values those examples carry (std_msgs/msg/String, example_interfaces/srv/AddTwoInts) and
the Jazzy values of the types `roco ros2` publishes, as `ros2 topic info -v` prints them.
"""

from __future__ import annotations

import struct

import pytest
from rosbags.typesys import Stores, get_typestore

from services.ros2 import rmw
from services.ros2.rmw import Attachment, Endpoint, EntityKind, Node, QoS, RmwError

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"
STRING = "std_msgs::msg::dds_::String_"
ADD_TWO_INTS = "example_interfaces::srv::dds_::AddTwoInts_"

# the design document, "Graph Cache", verbatim (its examples use domain 2)
LISTENER_NN = "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
LISTENER_MS = (
    "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
    f"{STRING}/{STRING_HASH}/::,10:,:,:,,"
)
TALKER_MP = (
    "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
    f"{STRING}/{STRING_HASH}/::,7:,:,:,,"
)
SERVER_SS = (
    "@ros2_lv/2/f9980ee0495eaafb3e38f0d19e2eae12/0/10/SS/%/%/add_two_ints_server/%add_two_ints/"
    f"{ADD_TWO_INTS}/{ADD_TWO_INTS_HASH}/::,10:,:,:,,"
)
CLIENT_SC = (
    "@ros2_lv/2/e1dc8d1b45ae8717fce78689cc655685/0/10/SC/%/%/add_two_ints_client/%add_two_ints/"
    f"{ADD_TWO_INTS}/{ADD_TWO_INTS_HASH}/::,10:,:,:,,"
)


def test_data_key_expressions_are_the_documented_ones() -> None:
    assert rmw.dds_type_name("std_msgs/msg/String") == STRING
    assert rmw.dds_type_name("example_interfaces/srv/AddTwoInts") == ADD_TWO_INTS
    assert rmw.topic_key(0, rmw.fully_qualified("chatter"), STRING, STRING_HASH) == (
        f"0/chatter/{STRING}/{STRING_HASH}"
    )
    assert rmw.topic_key(0, rmw.fully_qualified("chatter", "/robot1"), STRING, STRING_HASH) == (
        f"0/robot1/chatter/{STRING}/{STRING_HASH}"
    )
    assert rmw.topic_key(2, "/add_two_ints", ADD_TWO_INTS, ADD_TWO_INTS_HASH) == (
        f"2/add_two_ints/{ADD_TWO_INTS}/{ADD_TWO_INTS_HASH}"
    )


def _node(session: str, name: str) -> Node:
    return Node(domain=2, session_id=session, node_id=0, name=name)


def test_liveliness_tokens_are_the_documented_ones() -> None:
    listener = _node("aac3178e146ba6f1fc6e6a4085e77f21", "listener")
    assert rmw.node_token(listener) == LISTENER_NN
    sub = Endpoint(listener, 10, EntityKind.SUBSCRIPTION, "/chatter", STRING, STRING_HASH, QoS(depth=10))
    assert rmw.endpoint_token(sub) == LISTENER_MS
    talker = _node("8b20917502ee955ac4476e0266340d5c", "talker")
    pub = Endpoint(talker, 10, EntityKind.PUBLISHER, "/chatter", STRING, STRING_HASH, QoS(depth=7))
    assert rmw.endpoint_token(pub) == TALKER_MP
    server = _node("f9980ee0495eaafb3e38f0d19e2eae12", "add_two_ints_server")
    ss = Endpoint(
        server, 10, EntityKind.SERVICE, "/add_two_ints", ADD_TWO_INTS, ADD_TWO_INTS_HASH, QoS(depth=10)
    )
    assert rmw.endpoint_token(ss) == SERVER_SS
    client = _node("e1dc8d1b45ae8717fce78689cc655685", "add_two_ints_client")
    sc = Endpoint(
        client, 10, EntityKind.CLIENT, "/add_two_ints", ADD_TWO_INTS, ADD_TWO_INTS_HASH, QoS(depth=10)
    )
    assert rmw.endpoint_token(sc) == CLIENT_SC


@pytest.mark.parametrize("token", [LISTENER_NN, LISTENER_MS, TALKER_MP, SERVER_SS, CLIENT_SC])
def test_documented_tokens_parse_and_rebuild_byte_for_byte(token: str) -> None:
    entity = rmw.parse_token(token)
    rebuilt = rmw.node_token(entity) if isinstance(entity, Node) else rmw.endpoint_token(entity)
    assert rebuilt == token


def test_qos_strings() -> None:
    assert rmw.qos_string(rmw.DEFAULT_QOS) == "::,:,:,:,,"
    assert rmw.qos_string(QoS(depth=10)) == "::,10:,:,:,,"
    assert rmw.parse_qos("::,7:,:,:,,") == QoS(depth=7)
    odd = QoS(
        reliability=rmw.Reliability.BEST_EFFORT,
        durability=rmw.Durability.TRANSIENT_LOCAL,
        history=rmw.History.KEEP_ALL,
        depth=1,
        deadline=(1, 5),
        lifespan=(2, 0),
        liveliness=rmw.Liveliness.MANUAL_BY_TOPIC,
        lease=(3, 4),
    )
    assert rmw.qos_string(odd) == "2:1:2,1:1,5:2,0:3,3,4"
    assert rmw.parse_qos(rmw.qos_string(odd)) == odd


@pytest.mark.parametrize(
    "bad", ["", "::,10:,:,:,", "::,10:,:,:,,:", "9::,:,:,:,,", "::x,:,:,:,,", "::,10:,:,,:,,"]
)
def test_a_malformed_qos_string_is_refused(bad: str) -> None:
    with pytest.raises(RmwError):
        rmw.parse_qos(bad)


@pytest.mark.parametrize(
    "bad",
    [
        "@ros2_lv/2/zid/0/0/XX/%/%/listener",
        "@other/2/zid/0/0/NN/%/%/listener",
        "@ros2_lv/2/zid/0/0/NN/%/%",
        "@ros2_lv/2/zid/0/10/MS/%/%/listener/%chatter",
        "@ros2_lv/x/zid/0/0/NN/%/%/listener",
        LISTENER_MS.replace("::,10:,:,:,,", "::,10"),
    ],
)
def test_a_malformed_token_is_refused(bad: str) -> None:
    with pytest.raises(RmwError):
        rmw.parse_token(bad)


def test_attachment_is_the_documented_33_bytes() -> None:
    gid = bytes(range(16))
    data = Attachment(sequence=1, timestamp_ns=1_700_000_000_123_456_789, gid=gid).encode()
    # the design document: int64 LE sequence number, int64 LE ns since the epoch, one octet 16, the GID
    assert len(data) == rmw.ATTACHMENT_SIZE == 33
    assert data[:8] == b"\x01" + b"\x00" * 7
    assert data[8:16] == struct.pack("<q", 1_700_000_000_123_456_789)
    assert data[16] == 16
    assert data[17:] == gid
    assert Attachment.decode(data) == Attachment(1, 1_700_000_000_123_456_789, gid)


@pytest.mark.parametrize("bad", [b"", b"\x00" * 32, b"\x00" * 34, b"\x00" * 16 + b"\x08" + b"\x00" * 16])
def test_a_malformed_attachment_is_refused(bad: bytes) -> None:
    with pytest.raises(RmwError):
        Attachment.decode(bad)


def test_gids_are_16_octets_and_differ_per_token() -> None:
    assert len(rmw.gid_of(TALKER_MP)) == 16
    assert rmw.gid_of(TALKER_MP) == rmw.gid_of(TALKER_MP) != rmw.gid_of(LISTENER_MS)
    with pytest.raises(RmwError):
        Attachment(1, 1, b"short").encode()


def test_type_hashes_are_the_documented_rihs01() -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    assert rmw.type_hash(store, "std_msgs/msg/String") == STRING_HASH
    rmw.register_service(store, "example_interfaces/srv/AddTwoInts", "int64 a\nint64 b\n", "int64 sum\n")
    assert rmw.type_hash(store, "example_interfaces/srv/AddTwoInts") == ADD_TWO_INTS_HASH
    # Jazzy's hashes of what roco ros2 publishes (`ros2 topic info -v`, `ros2 interface`)
    assert rmw.type_hash(store, "sensor_msgs/msg/JointState") == (
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
    )
    assert rmw.type_hash(store, "tf2_msgs/msg/TFMessage") == (
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
    )
    assert rmw.type_hash(store, "sensor_msgs/msg/Image") == (
        "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"
    )


@pytest.mark.parametrize("bad", ["", "a//b", "/a/", "a b", "é", "x" * 300])
def test_a_bad_name_is_refused(bad: str) -> None:
    with pytest.raises(RmwError):
        rmw.fully_qualified(bad)
