"""The second, independent CDR encoder of the ROS 2 tests: mcap-ros2-support's dynamic encoder
(``mcap_ros2._dynamic.serialize_dynamic``), fed the same ``ros2msg`` schema text that roco writes
in its MCAP files, and a converter from rosbags' message objects to the plain values it takes."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the ros2 extra's rosbags is not installed")
dynamic = pytest.importorskip(
    "mcap_ros2._dynamic", reason="the ros2 extra's mcap-ros2-support is not installed"
)

from services.ros2 import messages  # noqa: E402


def plain(value: Any) -> Any:
    """A rosbags message (a dataclass, numpy arrays inside) as dicts, lists and bytes."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        return value.tobytes() if value.dtype == np.uint8 else value.tolist()
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


@functools.cache
def _encoder(typename: str) -> Callable[[Any], bytes]:
    encoders = dynamic.serialize_dynamic(typename, messages.message_definition(typename))
    return encoders[typename]


def mcap_ros2_cdr(typename: str, message: Any) -> bytes:
    """``message`` (a rosbags object) in CDR by mcap-ros2-support's encoder."""
    return bytes(_encoder(typename)(plain(message)))


def rosbags_cdr(typename: str, message: Any) -> bytes:
    """``message`` in CDR by rosbags (little endian, as rosbag2 writes)."""
    return bytes(messages.typestore().serialize_cdr(message, typename, little_endian=True))
