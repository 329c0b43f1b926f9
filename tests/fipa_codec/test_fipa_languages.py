"""The six content languages (paper §5.4, §5.6): every term type round-trips, bad content is
ContentError."""

from __future__ import annotations

import msgspec
import pytest
from fipa_strategies import SAMPLE_TERMS
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.fipa_codec.languages import (
    LANGUAGES,
    ContentError,
    decode_content,
    encode_content,
    language_of,
)
from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.l_hc import MAX_NOTICE_ABOUT, MAX_NOTICE_CHARS, Notice, TaskAtom
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.languages.l_wm import ObjectQuery


def test_the_six_languages_are_registered() -> None:
    language_of(ObjectQuery("x"))  # loads all
    assert set(LANGUAGES) == {"L_HC", "L_HFSM", "L_SW", "L_WM", "L_EX", "L_SD"}


def test_every_term_type_has_a_sample() -> None:
    language_of(ObjectQuery("x"))
    types = {t for lang in LANGUAGES.values() for t in lang.types}
    assert types == {type(t) for t in SAMPLE_TERMS}


@pytest.mark.parametrize("term", SAMPLE_TERMS, ids=lambda t: type(t).__name__)
def test_term_round_trips_in_its_language(term: msgspec.Struct) -> None:
    language, data = encode_content(term)
    assert type(term) in LANGUAGES[language].types
    decoded = decode_content(language, data)
    assert decoded == term
    assert type(decoded) is type(term)


@pytest.mark.parametrize("term", SAMPLE_TERMS, ids=lambda t: type(t).__name__)
def test_term_is_rejected_by_the_other_languages(term: msgspec.Struct) -> None:
    language, data = encode_content(term)
    for other in LANGUAGES:
        if other != language:
            try:
                decoded = decode_content(other, data)
            except ContentError:
                continue
            # a different language may only accept it as one of its own types
            assert type(decoded) in LANGUAGES[other].types


@pytest.mark.parametrize("language", ["L_XX", None, "", "l_wm"])
def test_unknown_language_is_content_error(language: str | None) -> None:
    with pytest.raises(ContentError, match="unknown content language"):
        decode_content(language, encode_content(ObjectQuery("jar"))[1])


@pytest.mark.parametrize(
    "data",
    [
        b"",
        b"\xc1",  # never used in msgpack
        msgspec.msgpack.encode({"type": "nope"}),  # unknown tag
        msgspec.msgpack.encode({"type": "object"}),  # missing field
        msgspec.msgpack.encode({"type": "object", "name": 3}),  # wrong type
        msgspec.msgpack.encode({"type": "sw", "state": "Sleeping"}),  # not an SWState
        msgspec.msgpack.encode([1, 2]),
        encode_content(ObjectQuery("jar"))[1][:-1],  # truncated
    ],
)
def test_bad_content_is_content_error(data: bytes) -> None:
    for language in LANGUAGES:
        with pytest.raises(ContentError, match=language):
            decode_content(language, data)


@given(st.binary(max_size=100), st.sampled_from(["L_HC", "L_HFSM", "L_SW", "L_WM", "L_EX", "L_SD"]))
@settings(max_examples=500)
def test_random_content_gives_content_error_only(data: bytes, language: str) -> None:
    try:
        term = decode_content(language, data)
    except ContentError as exc:
        assert isinstance(exc, ValueError)
    else:
        assert type(term) in LANGUAGES[language].types


def test_term_outside_every_language() -> None:
    with pytest.raises(ContentError, match="no content language"):
        encode_content(TaskAtom("pour"))  # a part of terms, not a term itself


class _Probe(msgspec.Struct, tag="probe"):
    pass


def test_register_rejects_duplicates() -> None:
    with pytest.raises(ValueError, match="registered twice"):
        register(Language("L_SW", "O_RoCo", (TaskAtom,)))
    with pytest.raises(ValueError, match="already belongs"):
        register(Language("L_NEW", "O_RoCo", (_Probe, SWStatus)))
    assert "L_NEW" not in LANGUAGES
    with pytest.raises(ContentError):  # _Probe was not half-registered to L_NEW
        language_of(_Probe())


@pytest.mark.parametrize(
    ("notice", "why"),
    [
        (Notice(text=""), "length >= 1"),
        (Notice(text="x" * (MAX_NOTICE_CHARS + 1)), f"length <= {MAX_NOTICE_CHARS}"),
        (Notice(text="t", about=("cup",) * (MAX_NOTICE_ABOUT + 1)), f"length <= {MAX_NOTICE_ABOUT}"),
        (Notice(text="t", about=("",)), "length >= 1"),
    ],
    ids=["empty", "too long", "too many names", "empty name"],
)
def test_a_notice_outside_its_bounds_does_not_decode(notice: Notice, why: str) -> None:
    """L_HC ``Notice`` (a_hi's notices): text 1..500 characters, at most 16 names of things,
    none empty; outside, its receiver cannot read it (and answers not-understood)."""
    language, data = encode_content(notice)  # encoding does not check the bounds: decoding does
    with pytest.raises(ContentError, match=why):
        decode_content(language, data)
    longest = Notice(text="x" * MAX_NOTICE_CHARS)
    assert decode_content(language, encode_content(longest)[1]) == longest
