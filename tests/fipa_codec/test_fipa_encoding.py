"""msgpack and JSON encodings of a communicate (FIPA SC00061 parameters): round trips, strict
rejection of bad bytes as DecodeError, and the JSON form as documented for tools outside
Python (field list, base64 content, agent identifiers as arrays, JSON Schema)."""

from __future__ import annotations

import base64
import contextlib
import json
import math

import msgspec
import pytest
from fipa_strategies import communicates, full_communicate
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shared.fipa_codec import Communicate, DecodeError, Performative, decode, encode, encoding
from shared.fipa_codec.aid import AgentIdentifier
from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES, decode_json, encode_json, json_schema


@pytest.mark.parametrize("performative", list(Performative))
def test_every_act_with_every_parameter_round_trips(performative: Performative) -> None:
    msg = full_communicate(performative)
    assert decode(encode(msg)) == msg
    assert decode_json(encode_json(msg)) == msg


def test_there_are_22_acts() -> None:
    assert len(Performative) == 22


def test_json_uses_fipa_parameter_names() -> None:
    raw = msgspec.json.decode(encode_json(full_communicate()))
    assert set(raw) == {
        "performative",
        "sender",
        "receiver",
        "reply-to",
        "content",
        "language",
        "encoding",
        "ontology",
        "protocol",
        "conversation-id",
        "reply-with",
        "in-reply-to",
        "reply-by",
        "user-params",
    }


@given(communicates())
@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
def test_msgpack_round_trip(msg: Communicate) -> None:
    assert decode(encode(msg)) == msg


@given(communicates())
@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
def test_json_round_trip(msg: Communicate) -> None:
    assert decode_json(encode_json(msg)) == msg


def _decodes_or_decode_error(data: bytes) -> None:
    try:
        result = decode(data)
    except DecodeError as exc:
        assert exc.reason
    else:
        assert isinstance(result, Communicate)


@given(st.binary(max_size=200))
@settings(max_examples=1000)
def test_random_bytes_give_decode_error_only(data: bytes) -> None:
    _decodes_or_decode_error(data)


@given(communicates(), st.data())
@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
def test_truncated_and_mutated_bytes_give_decode_error_only(msg: Communicate, data: st.DataObject) -> None:
    wire = encode(msg)
    cut = data.draw(st.integers(0, len(wire) - 1))
    with pytest.raises(DecodeError):
        decode(wire[:cut])
    pos = data.draw(st.integers(0, len(wire) - 1))
    byte = data.draw(st.integers(0, 255))
    _decodes_or_decode_error(wire[:pos] + bytes([byte]) + wire[pos + 1 :])


@given(st.text(max_size=100) | st.binary(max_size=100))
@settings(max_examples=500)
def test_random_json_gives_decode_error_only(data: str | bytes) -> None:
    with contextlib.suppress(DecodeError):
        decode_json(data)


@pytest.mark.parametrize(
    "obj",
    [
        {"performative": "shout"},  # unknown performative
        {"performative": "INFORM"},  # wrong case
        {},  # no performative
        {"performative": 5},
        {"performative": "inform", "receiver": "a_km"},  # wrong type
        {"performative": "inform", "receiver": [["1bad", []]]},  # bad agent name
        {"performative": "inform", "sender": ["a_co", "tcp/x"]},  # addresses not a list
        {"performative": "inform", "content": "@@@"},  # content must be bytes (base64)
        {"performative": "inform", "reply-by": "tomorrow"},
        {"performative": "inform", "user-params": {"priority": "1"}},  # no X-
        {"performative": "inform", "user-params": {"X-a": 1}},
        [1, 2, 3],
        "inform",
        None,
    ],
)
def test_wrong_structure_is_decode_error(obj: object) -> None:
    with pytest.raises(DecodeError):
        decode(msgspec.msgpack.encode(obj))
    with pytest.raises(DecodeError):
        decode_json(msgspec.json.encode(obj))


def test_oversized_input_is_decode_error() -> None:
    wire = encode(Communicate(performative=Performative.INFORM, content=b"x" * 2000))
    with pytest.raises(DecodeError, match="exceeds"):
        decode(wire, max_size=1000)


def test_unknown_fields_are_ignored_for_forward_compatibility() -> None:
    wire = msgspec.msgpack.encode({"performative": "inform", "x-future": 1})
    assert decode(wire) == Communicate(performative=Performative.INFORM)


def test_construction_checks() -> None:
    with pytest.raises(ValueError, match="X-"):
        Communicate(performative=Performative.INFORM, user_params={"priority": "1"})
    with pytest.raises(ValueError, match="agent name"):
        AgentIdentifier("1a")


def test_reply_carries_the_conversation() -> None:
    msg = full_communicate(Performative.QUERY_REF)
    reply = msg.reply(Performative.INFORM, AgentIdentifier("a_km"), content=b"\x80")
    assert reply.receiver == msg.reply_to
    assert reply.in_reply_to == msg.reply_with
    assert (reply.protocol, reply.conversation_id) == (msg.protocol, msg.conversation_id)
    assert reply.encoding == "msgpack"


# -- the JSON form for tools outside Python -------------------------------------------------------


def test_json_docstring_example_is_the_encoding() -> None:
    doc = encoding.__doc__ or ""
    example = doc[doc.index('{"performative"') : doc.index("}}") + 2]
    one_line = "".join(line.strip() for line in example.splitlines())
    msg = decode_json(one_line)
    assert msg == Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier("a_co", ("tcp/127.0.0.1:7447",)),
        receiver=(AgentIdentifier("a_km"),),
        content=b"\x81\xa4type",
        language="L_WM",
        reply_by=1795275000.123,
        user_params={"X-priority": "2"},
    )
    assert encode_json(msg).decode() == one_line


def test_json_written_by_another_tool() -> None:
    text = json.dumps(
        {
            "performative": "request",
            "sender": ["a_hi"],  # the address list may be left out
            "receiver": [["a_co", ["tcp/127.0.0.1:7447"]], ["a_ta", [], "from the future"]],
            "content": base64.b64encode("pour the jar → bowl".encode()).decode(),
            "language": "L_HC",
            "conversation-id": "c-1",
            "reply-by": 1795275000,
            "user-params": {"X-priority": "1", "x-note": "lower-case prefix"},
            "x-unknown-field": [1, 2],
        }
    )
    msg = decode_json(text)
    assert msg.sender == AgentIdentifier("a_hi")
    assert msg.receiver == (AgentIdentifier("a_co", ("tcp/127.0.0.1:7447",)), AgentIdentifier("a_ta"))
    assert msg.content.decode() == "pour the jar → bowl"
    assert msg.reply_by == 1795275000.0
    assert msg.user_params == {"X-priority": "1", "x-note": "lower-case prefix"}
    assert decode_json(encode_json(msg)) == msg


def test_json_leaves_defaults_out() -> None:
    assert encode_json(Communicate(performative=Performative.CFP)) == b'{"performative":"cfp"}'


def test_json_schema_lists_the_fields() -> None:
    schema = json_schema()
    props = schema["$defs"]["Communicate"]["properties"]
    assert set(props) == set(msgspec.json.decode(encode_json(full_communicate())))
    assert schema["$defs"]["Communicate"]["required"] == ["performative"]
    assert props["content"]["contentEncoding"] == "base64"
    assert schema["$defs"]["Performative"]["enum"] == [p.value for p in Performative]
    assert schema["$defs"]["AgentIdentifier"]["type"] == "array"
    json.dumps(schema)  # a plain JSON document


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf])
def test_json_refuses_non_finite_reply_by(t: float) -> None:
    with pytest.raises(ValueError, match="not finite"):
        encode_json(Communicate(performative=Performative.INFORM, reply_by=t))
    assert (
        decode(encode(Communicate(performative=Performative.INFORM, reply_by=math.inf))).reply_by == math.inf
    )


def test_oversized_json_is_decode_error() -> None:
    wire = encode_json(Communicate(performative=Performative.INFORM, content=b"x" * 2000))
    with pytest.raises(DecodeError, match="exceeds"):
        decode_json(wire, max_size=1000)
    assert decode_json(wire, max_size=MAX_COMMUNICATE_BYTES).content == b"x" * 2000
    assert decode_json(bytearray(wire)).content == b"x" * 2000
