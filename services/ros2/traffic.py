"""One recorded communicate as a ``roco_msgs/msg/Communicate`` and back: the traffic record's
fields (services/recorder/record.py :class:`TrafficRecord`), the communicate's 13 FIPA
parameters (FIPA SC00061) and its msgpack bytes, so that the record and its payload come back
exactly from a bag.

Absent texts travel as ``""``, absent numbers as NaN (times) or −1 (``sn``); a record whose
optional texts were empty strings therefore comes back with None there (the recorder never
writes such records: a FIPA word or identifier is never empty).
"""

from __future__ import annotations

import base64
import math
from typing import Any

import numpy as np

from services.recorder.record import TrafficRecord
from services.ros2 import messages
from shared.fipa_codec import Communicate, DecodeError, decode
from shared.fipa_codec.string_form import content_as_json

NANOS = 1_000_000_000


def content_text(comm: Communicate) -> str:
    """``comm``'s content as text: the JSON of its term in its language
    (``content_as_json``), else the content itself when it is UTF-8 text, else
    ``<n bytes, base64 …>`` (as ``to_string(human=True)`` writes it, docs/string_form.md)."""
    if not comm.content:
        return ""
    rendered = content_as_json(comm)
    if rendered is not None:
        return rendered
    try:
        return comm.content.decode("utf-8")
    except UnicodeDecodeError:
        return f"<{len(comm.content)} bytes, base64 {base64.b64encode(comm.content).decode()}>"


def time_msg(ns: int) -> Any:
    """A ``builtin_interfaces/msg/Time`` of ``ns`` (≥ 0) nanoseconds."""
    cls = messages.typestore().types["builtin_interfaces/msg/Time"]
    return cls(sec=ns // NANOS, nanosec=ns % NANOS)


def _text(value: str | None) -> str:
    return "" if value is None else value


def _optional(text: str) -> str | None:
    return text or None


def _number(value: float | None) -> float:
    return math.nan if value is None else value


def _decoded(payload: bytes | None) -> Communicate | None:
    try:
        return decode(payload) if payload else None
    except DecodeError:
        return None


def payload_parameters(payload: bytes | None) -> dict[str, Any]:
    """The parameters of a ``roco_msgs/msg/Communicate`` that the traffic record does not
    hold, read from the communicate's ``payload``: all empty (reply-by NaN) when it is lost
    or does not decode."""
    comm = _decoded(payload)
    if comm is None:
        return {
            "reply_to": [],
            "content": "",
            "encoding": "",
            "reply_with": "",
            "in_reply_to": "",
            "reply_by": math.nan,
        }
    return {
        "reply_to": [a.name for a in comm.reply_to],
        "content": content_text(comm),
        "encoding": _text(comm.encoding),
        "reply_with": _text(comm.reply_with),
        "in_reply_to": _text(comm.in_reply_to),
        "reply_by": _number(comm.reply_by),
    }


def to_message(rec: TrafficRecord, payload: bytes | None, stamp_ns: int) -> Any:
    """The ``roco_msgs/msg/Communicate`` of record ``rec`` and its ``payload`` (None: lost),
    stamped ``stamp_ns`` (robot time, ns; 0 when unknown). Parameters the record does not
    hold come from the payload (:func:`payload_parameters`)."""
    cls = messages.typestore().types[messages.COMMUNICATE]
    return cls(
        stamp=time_msg(stamp_ns),
        wall_time=rec.t,
        key=rec.key,
        channel=rec.channel,
        size=rec.size,
        performative=rec.performative,
        sender=rec.sender,
        receiver=list(rec.receivers),
        language=_text(rec.language),
        ontology=_text(rec.ontology),
        protocol=_text(rec.protocol),
        conversation_id=_text(rec.conversation_id),
        incarnation=rec.incarnation,
        seq=rec.seq,
        source=_text(rec.source),
        sn=-1 if rec.sn is None else rec.sn,
        t_sent=_number(rec.t_sent),
        late=rec.late,
        key_sender=_text(rec.key_sender),
        part=rec.part,
        payload=np.frombuffer(payload or b"", dtype=np.uint8),
        **payload_parameters(payload),
    )


def from_message(msg: Any) -> tuple[TrafficRecord, bytes | None]:
    """The record and payload (None when it was lost) a ``roco_msgs/msg/Communicate``
    carries: the inverse of :func:`to_message`."""
    payload = bytes(msg.payload)
    rec = TrafficRecord(
        seq=int(msg.seq),
        t=float(msg.wall_time),
        size=int(msg.size),
        channel=msg.channel,
        sender=msg.sender,
        receivers=tuple(msg.receiver),
        performative=msg.performative,
        protocol=_optional(msg.protocol),
        conversation_id=_optional(msg.conversation_id),
        language=_optional(msg.language),
        ontology=_optional(msg.ontology),
        key=msg.key,
        incarnation=msg.incarnation,
        source=_optional(msg.source),
        sn=None if msg.sn < 0 else int(msg.sn),
        t_sent=None if math.isnan(msg.t_sent) else float(msg.t_sent),
        late=bool(msg.late),
        key_sender=_optional(msg.key_sender),
        part=int(msg.part),
    )
    return rec, payload or None
