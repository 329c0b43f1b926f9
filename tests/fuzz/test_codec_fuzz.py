"""The codec under bad input: decoding anything raises DecodeError and nothing
else; the size limit holds on encode and decode; deeply nested input is an error, not a
crash; 1 MB of content (the benchmark's largest) still passes."""

from __future__ import annotations

import contextlib

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.fipa_codec import (
    AgentIdentifier,
    Communicate,
    DecodeError,
    EncodeError,
    Performative,
    decode,
    encode,
)
from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES, decode_json, encode_json
from shared.fipa_codec.languages import ContentError, decode_content, load_all
from tests.fipa_codec.fipa_strategies import communicates
from tests.fuzz.strategies import _nested_plan


@settings(max_examples=2000, deadline=None)
@given(st.binary(max_size=512))
def test_random_bytes_decode_or_raise_decode_error_only(data: bytes) -> None:
    try:
        decode(data)
    except DecodeError as exc:
        assert exc.reason and "\n" not in exc.reason


@settings(max_examples=300, deadline=None)
@given(communicates(), st.data())
def test_every_truncation_of_a_valid_encoding_is_a_decode_error(
    msg: Communicate, data: st.DataObject
) -> None:
    raw = encode(msg)
    cut = data.draw(st.integers(0, len(raw) - 1))
    with pytest.raises(DecodeError):
        decode(raw[:cut])


@settings(max_examples=300, deadline=None)
@given(
    st.recursive(
        st.none() | st.integers(-5, 5) | st.text(max_size=5),
        lambda c: st.lists(c) | st.dictionaries(st.text(max_size=5), c),
        max_leaves=30,
    )
)
def test_arbitrary_msgpack_values_are_decode_errors_unless_a_communicate(value: object) -> None:
    with contextlib.suppress(DecodeError):
        decode(msgspec.msgpack.encode(value))


@pytest.mark.parametrize("depth", [100, 2_000, 100_000])
def test_deeply_nested_msgpack_is_a_decode_error(depth: int) -> None:
    nested = b"\x91" * depth + b"\xc0"
    with pytest.raises(DecodeError):
        decode(nested)
    with pytest.raises(DecodeError):
        decode(b"\x81\xacperformative" + nested)


@pytest.mark.parametrize("depth", [1_500, 20_000, 200_000])
def test_content_nested_beyond_the_stack_is_a_content_error(depth: int) -> None:
    with pytest.raises(ContentError, match="nested too deeply"):
        decode_content("L_HFSM", _nested_plan(depth))


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(sorted(load_all())), st.binary(max_size=256))
def test_random_content_is_a_content_error_in_every_language(language: str, body: bytes) -> None:
    with contextlib.suppress(ContentError):
        decode_content(language, body)


def _big(n: int) -> Communicate:
    return Communicate(performative=Performative.INFORM, sender=AgentIdentifier("a_km"), content=b"x" * n)


def test_one_megabyte_of_content_passes_both_ways() -> None:
    msg = _big(1_000_000)
    assert decode(encode(msg)) == msg
    assert decode_json(encode_json(msg)) == msg


def test_the_size_limit_holds_on_encode_and_decode() -> None:
    overhead = len(encode(_big(0)))
    at_limit = _big(MAX_COMMUNICATE_BYTES - overhead - 4)  # bin32 header: 4 more bytes
    raw = encode(at_limit)
    assert len(raw) <= MAX_COMMUNICATE_BYTES and decode(raw) == at_limit
    over = _big(MAX_COMMUNICATE_BYTES)
    with pytest.raises(EncodeError, match="exceeds the communicate limit"):
        encode(over)
    raw = encode(over, max_size=2 * MAX_COMMUNICATE_BYTES)
    with pytest.raises(DecodeError) as info:
        decode(raw)
    assert info.value.oversized
    with pytest.raises(DecodeError):
        decode_json(b" " * (MAX_COMMUNICATE_BYTES + 1))
    with pytest.raises(EncodeError):
        encode_json(over)
