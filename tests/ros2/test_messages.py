"""roco_msgs in rosbags' type store: registered, hashed (REP 2011 RIHS01, golden values of
standard types from ROS 2 sources) and encoded byte for byte as mcap-ros2-support encodes them."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from services.ros2 import messages
from tests.ros2.cdr import mcap_ros2_cdr, rosbags_cdr

GOLDEN_RIHS01 = {
    # the task's given value (rmw_zenoh key of /chatter)
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    # an rmw_zenoh liveliness token of /tf in a C++ client's source
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    # goldens pinned by a rosidl-generated package's tests
    "geometry_msgs/msg/PoseStamped": (
        "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"
    ),
    # a generated Python binding's docstring
    "sensor_msgs/msg/Range": "RIHS01_b42b62562e93cbfe9d42b82fe5994dfa3d63d7d5c90a317981703f7388adff3a",
}
"""RIHS01 hashes found written in ROS 2 code, not computed by rosbags."""


@pytest.mark.parametrize("typename", sorted(GOLDEN_RIHS01))
def test_standard_type_hashes_are_rosidls(typename: str) -> None:
    assert messages.type_hash(typename) == GOLDEN_RIHS01[typename]


def test_roco_types_are_registered_with_their_hashes() -> None:
    hashes = {name: messages.type_hash(name) for name in messages.MESSAGES}
    assert all(h.startswith("RIHS01_") and len(h) == 7 + 64 for h in hashes.values())
    assert len(set(hashes.values())) == len(hashes)
    with pytest.raises(KeyError):
        messages.type_hash("roco_msgs/msg/Nothing")


def test_say_service_is_a_request_and_a_response() -> None:
    request, response = messages.SAY_SRV.split("---\n")
    assert request.split()[:2] == ["string", "sentence"]
    fields = [line.split()[:2] for line in response.splitlines() if not line.startswith("#")]
    assert fields == [
        ["bool", "ok"],
        ["string", "outcome"],
        ["string", "report"],
    ]


def communicate() -> Any:
    store = messages.typestore()
    t = store.types["builtin_interfaces/msg/Time"]
    return store.types[messages.COMMUNICATE](
        stamp=t(sec=12, nanosec=500_000_000),
        wall_time=1_800_000_000.25,
        key="roco/fipa/C3/a_pl/a_km",
        channel="C3",
        size=5,
        performative="query-ref",
        sender="a_pl",
        receiver=["a_km", "a_co"],
        reply_to=[],
        content='{"query":"pose","of":"jar"} – ünïcode',
        language="L_WM",
        encoding="msgpack",
        ontology="",
        protocol="fipa-query",
        conversation_id="c-1",
        reply_with="r-1",
        in_reply_to="",
        reply_by=math.nan,
        incarnation="abc",
        seq=7,
        source="s:1",
        sn=-1,
        t_sent=1_800_000_000.125,
        late=True,
        key_sender="a_pl",
        part=1,
        payload=np.frombuffer(b"\x81\xa1a\x01\xff", dtype=np.uint8),
    )


def test_communicate_cdr_is_byte_equal_between_rosbags_and_mcap_ros2() -> None:
    msg = communicate()
    ours = rosbags_cdr(messages.COMMUNICATE, msg)
    assert ours == mcap_ros2_cdr(messages.COMMUNICATE, msg)
    back: Any = messages.typestore().deserialize_cdr(ours, messages.COMMUNICATE)
    assert back.receiver == ["a_km", "a_co"] and bytes(back.payload) == b"\x81\xa1a\x01\xff"
    assert math.isnan(back.reply_by) and back.sn == -1


@pytest.mark.parametrize("typename", [messages.TASK_STATE, messages.SAY_PROGRESS])
def test_other_roco_messages_are_byte_equal(typename: str) -> None:
    store = messages.typestore()
    cls: Any = store.types[typename]
    values = {
        name: store.types["builtin_interfaces/msg/Time"](sec=3, nanosec=7) if name == "stamp" else f"{name}-x"
        for name in (f.name for f in dataclasses.fields(cls))
    }
    msg = cls(**values)
    assert rosbags_cdr(typename, msg) == mcap_ros2_cdr(typename, msg)
