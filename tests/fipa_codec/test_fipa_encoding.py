"""msgpack and JSON encodings of a communicate (FIPA SC00061 parameters): round trips, strict
rejection of bad bytes as DecodeError, agent identifiers in full (SC00023 §4: resolvers and
user-defined parameters) and the wire compatibility of their encoding, and the JSON form as
documented for tools outside Python (field list, base64 content, agent identifiers as arrays,
JSON Schema)."""

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
from shared.fipa_codec.aid import MAX_AID_DEPTH, AgentIdentifier
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


# -- agent identifiers in full (SC00023 §4): resolvers and user-defined parameters --------------

FULL_AID = AgentIdentifier(
    "da0@jade-platform",
    ("http://robolab:7778/acc",),
    (AgentIdentifier("df@jade-platform", resolvers=(AgentIdentifier("ams"),), user=(("X-k", "v"),)),),
    (("X-JADE-agent-classname", "examples.PingAgent"), ("x-weight", "0.5")),
)


@pytest.mark.parametrize(
    ("kwargs", "reason"),
    [
        ({"name": "a_co\n"}, "agent name"),  # no trailing newline (re "$" would let it through)
        ({"name": "a", "user": (("priority", "1"),)}, "user parameter name"),
        ({"name": "a", "user": (("X-", "1"),)}, "user parameter name"),
        ({"name": "a", "user": (("X-a b", "1"),)}, "user parameter name"),
        ({"name": "a", "user": (("X-a(", "1"),)}, "user parameter name"),
        ({"name": "a", "user": (("X-a\n", "1"),)}, "user parameter name"),
        ({"name": "a", "user": (("X-a", "1"), ("X-a", "2"))}, "repeated"),
    ],
)
def test_agent_identifier_checks(kwargs: dict[str, object], reason: str) -> None:
    with pytest.raises(ValueError, match=reason):
        AgentIdentifier(**kwargs)  # type: ignore[arg-type]


def _chain(depth: int) -> AgentIdentifier:
    agent = AgentIdentifier("r")
    for _ in range(depth - 1):
        agent = AgentIdentifier("r", resolvers=(agent,))
    return agent


def test_agent_identifier_user_names_and_depth() -> None:
    agent = AgentIdentifier("a", user=(("X-a", "1"), ("x-a", "2"), ('X-é#"', "")))  # spelling counts
    assert [k for k, _ in agent.user] == ["X-a", "x-a", 'X-é#"']
    assert hash(FULL_AID) == hash(msgspec.structs.replace(FULL_AID))  # frozen and hashable
    assert msgspec.structs.replace(FULL_AID, user=FULL_AID.user[::-1]) != FULL_AID  # in order
    assert str(FULL_AID) == "da0@jade-platform"
    deepest = _chain(MAX_AID_DEPTH)
    with pytest.raises(ValueError, match="nested deeper"):
        AgentIdentifier("r", resolvers=(deepest,))
    wire = encode(Communicate(performative=Performative.INFORM, sender=deepest))
    assert decode(wire).sender == deepest
    at = wire.index(b"\x94\xa1r")  # the outer agent identifier (the sender, last), wrapped in one more
    too_deep = wire[:at] + b"\x94\xa1r\x90\x91" + wire[at:] + b"\x90"
    with pytest.raises(DecodeError, match="nested deeper"):
        decode(too_deep)


def test_agent_identifiers_nested_past_the_stack_are_decode_error() -> None:
    # {"performative": "inform", "sender": ["r", [], [["r", [], [… ["r"] …]]]]}, 100 000 deep
    head = b"\x82\xacperformative\xa6inform\xa6sender"
    deep = head + b"\x93\xa1r\x90\x91" * 100_000 + b"\x91\xa1r"
    with pytest.raises(DecodeError, match="nested too deeply"):
        decode(deep)
    deep_json = '{"performative":"inform","sender":' + '["r",[],[' * 100_000 + '["r"]' + "]]" * 100_000 + "}"
    with pytest.raises(DecodeError, match="nested too deeply"):
        decode_json(deep_json)


def test_full_agent_identifier_round_trips() -> None:
    msg = Communicate(performative=Performative.INFORM, sender=FULL_AID, receiver=(FULL_AID, _chain(5)))
    assert decode(encode(msg)) == msg
    assert decode_json(encode_json(msg)) == msg
    raw = msgspec.json.decode(encode_json(msg))
    assert raw["sender"] == [
        "da0@jade-platform",
        ["http://robolab:7778/acc"],
        [["df@jade-platform", [], [["ams", [], [], []]], [["X-k", "v"]]]],
        [["X-JADE-agent-classname", "examples.PingAgent"], ["x-weight", "0.5"]],
    ]


# -- wire compatibility: communicates encoded before resolvers and user parameters existed -------

# msgpack of a communicate as roco wrote it before agent identifiers had resolvers and user
# parameters (commit 8caaaf8): every agent identifier the two-element array [name, addresses]
OLD_WIRE = bytes.fromhex(
    "8bac706572666f726d6174697665a772657175657374a673656e64657292a4615f636f91b27463702f3132372e302e30"
    "2e313a37343437a872656365697665729292a4615f74619092a561675f657892b17463702f31302e302e302e323a3734"
    "3437b17564702f31302e302e302e323a37343438a87265706c792d746f9192a4615f686990a7636f6e74656e74c40681"
    "a474797065a86c616e6775616765a44c5f4843a8656e636f64696e67a76d73677061636ba870726f746f636f6cac6669"
    "70612d72657175657374af636f6e766572736174696f6e2d6964a6632d61623132a87265706c792d6279cb41dac06e3e"
    "07df3bab757365722d706172616d7381aa582d7072696f72697479a132"
)
OLD_JSON = (
    '{"performative":"request","sender":["a_co",["tcp/127.0.0.1:7447"]],"receiver":[["a_ta",[]],'
    '["ag_ex",["tcp/10.0.0.2:7447","udp/10.0.0.2:7448"]]],"reply-to":[["a_hi",[]]],"content":"gaR0eXBl",'
    '"language":"L_HC","encoding":"msgpack","protocol":"fipa-request","conversation-id":"c-ab12",'
    '"reply-by":1795275000.123,"user-params":{"X-priority":"2"}}'
)
OLD_MSG = Communicate(
    performative=Performative.REQUEST,
    sender=AgentIdentifier("a_co", ("tcp/127.0.0.1:7447",)),
    receiver=(AgentIdentifier("a_ta"), AgentIdentifier("ag_ex", ("tcp/10.0.0.2:7447", "udp/10.0.0.2:7448"))),
    reply_to=(AgentIdentifier("a_hi"),),
    content=b"\x81\xa4type",
    language="L_HC",
    encoding="msgpack",
    protocol="fipa-request",
    conversation_id="c-ab12",
    reply_by=1795275000.123,
    user_params={"X-priority": "2"},
)


def test_communicates_encoded_before_still_decode() -> None:
    assert decode(OLD_WIRE) == OLD_MSG
    assert decode_json(OLD_JSON) == OLD_MSG
    assert msgspec.msgpack.decode(b"\x91\xa1a", type=AgentIdentifier) == AgentIdentifier("a")  # ["a"]


def test_agent_identifier_wire_form() -> None:
    """[name, addresses, resolvers, user]: msgspec writes the empty trailing items too
    (omit_defaults does not apply to array_like structs), two bytes more than [name, addresses]."""
    assert msgspec.msgpack.encode(AgentIdentifier("a_co")) == b"\x94\xa4a_co\x90\x90\x90"
    assert len(encode(OLD_MSG)) == len(OLD_WIRE) + 2 * 4  # four agent identifiers
    assert msgspec.json.encode(AgentIdentifier("a_co", ("tcp/h:1",))) == b'["a_co",["tcp/h:1"],[],[]]'


class _OldAgentIdentifier(msgspec.Struct, frozen=True, array_like=True):
    """AgentIdentifier as it was before resolvers and user parameters."""

    name: str
    addresses: tuple[str, ...] = ()


def test_readers_from_before_read_new_agent_identifiers_without_the_new_fields() -> None:
    old = msgspec.msgpack.decode(msgspec.msgpack.encode(FULL_AID), type=_OldAgentIdentifier)
    assert old == _OldAgentIdentifier("da0@jade-platform", ("http://robolab:7778/acc",))
    old = msgspec.json.decode(msgspec.json.encode(FULL_AID), type=_OldAgentIdentifier)
    assert old.name == "da0@jade-platform"


@pytest.mark.parametrize(
    "sender",
    [
        ["a", [], [["9"]]],  # resolver with a bad name
        ["a", [], [], [["priority", "1"]]],  # user parameter without X-
        ["a", [], [], [["X-a b", "1"]]],
        ["a", [], [], [["X-a", "1"], ["X-a", "2"]]],
        ["a", [], [], [["X-a"]]],  # a pair, not a name alone
        ["a", [], [], [["X-a", 1]]],
        ["a", [], "r"],
    ],
)
def test_bad_agent_identifier_is_decode_error(sender: object) -> None:
    obj = {"performative": "inform", "sender": sender}
    with pytest.raises(DecodeError):
        decode(msgspec.msgpack.encode(obj))
    with pytest.raises(DecodeError):
        decode_json(msgspec.json.encode(obj))


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
    # the agent identifier example
    start = doc.index('["da0@jade-platform"')
    end = doc.index('PingAgent"]]]', start) + len('PingAgent"]]]')
    aid_text = "".join(line.strip() for line in doc[start:end].splitlines())
    agent = msgspec.json.decode(aid_text, type=AgentIdentifier)
    assert agent == AgentIdentifier(
        "da0@jade-platform",
        ("http://robolab:7778/acc",),
        (AgentIdentifier("df@jade-platform"),),
        (("X-JADE-agent-classname", "examples.PingAgent"),),
    )
    assert msgspec.json.encode(agent).decode() == aid_text


def test_json_written_by_another_tool() -> None:
    text = json.dumps(
        {
            "performative": "request",
            "sender": ["a_hi"],  # the address list may be left out
            "receiver": [["a_co", ["tcp/127.0.0.1:7447"]], ["a_ta", [], [], [], "from the future"]],
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


def test_json_schema_documents_the_agent_identifier() -> None:
    aid_schema = json.loads(json.dumps(json_schema()))["$defs"]["AgentIdentifier"]
    assert aid_schema["minItems"] == 1
    name, addresses, resolvers, user = aid_schema["prefixItems"]
    for item, word in [(name, "name"), (addresses, "addresses"), (resolvers, "resolvers"), (user, "user")]:
        assert item["description"].startswith(word + ":")
    assert name["pattern"] == '^[^\\x00-\\x20()#0-9\\-@"][^\\x00-\\x20()]{0,254}$'  # a SC00070 Word
    assert addresses["items"] == {"type": "string"} and addresses["default"] == []
    assert resolvers["items"] == {"$ref": "#/$defs/AgentIdentifier"} and resolvers["default"] == []
    pair = user["items"]
    assert (pair["type"], pair["minItems"], pair["maxItems"]) == ("array", 2, 2)
    key, value = pair["prefixItems"]
    assert key["pattern"] == "^[Xx]-[^\\x00-\\x20()]+$" and value["type"] == "string"


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
