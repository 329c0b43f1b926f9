"""The six content languages (paper §5.4, §5.6): every term type round-trips, bad content is
ContentError."""

from __future__ import annotations

from typing import Annotated

import msgspec
import pytest
from fipa_strategies import SAMPLE_TERMS
from hypothesis import given, settings
from hypothesis import strategies as st
from term_sample import build_sample

from services.spec.terms import load_spec_terms
from shared.fipa_codec.languages import (
    LANGUAGES,
    ContentError,
    base,
    decode_content,
    encode_content,
    extend,
    language_of,
    load_all,
)
from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.l_hc import MAX_NOTICE_ABOUT, MAX_NOTICE_CHARS, Notice, TaskAtom
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import ObjectQuery


def test_the_six_languages_are_registered() -> None:
    language_of(ObjectQuery("x"))  # loads all
    assert set(LANGUAGES) == {"L_HC", "L_HFSM", "L_SW", "L_WM", "L_EX", "L_SD"}


def _registered() -> list[type[msgspec.Struct]]:
    """Every term of every language: the codec's, and the specification's agents' own (its
    ``terms`` modules, services/spec/terms.py; those of docs/spec.md's walk-through where it was
    added)."""
    load_all()
    load_spec_terms()
    return [t for lang in LANGUAGES.values() for t in lang.types]


def test_every_term_type_has_a_sample_that_round_trips() -> None:
    """A hand-written sample (SAMPLE_TERMS, for the codec's own terms) or one built from the
    term's declaration (term_sample.py: an agent's own terms, services/spec/terms.py)."""
    hand = {type(t): t for t in SAMPLE_TERMS}
    assert set(hand) <= set(_registered())
    for kind in _registered():
        term = hand.get(kind) or build_sample(kind)
        assert decode_content(*encode_content(term)) == term, kind.__name__


@pytest.mark.parametrize("kind", _registered(), ids=lambda t: t.__name__)
def test_a_sample_built_from_the_declaration_round_trips(kind: type[msgspec.Struct]) -> None:
    term = build_sample(kind)
    assert type(term) is kind
    assert decode_content(*encode_content(term)) == term


def test_a_sample_is_built_for_an_agents_own_term() -> None:
    class Watched(msgspec.Struct, frozen=True, tag="watched_probe"):
        name: Annotated[str, msgspec.Meta(min_length=2)]
        count: Annotated[int, msgspec.Meta(gt=3)]
        state: SWState
        seen: tuple[float, ...] = ()

    languages, by_type = dict(LANGUAGES), dict(base._BY_TYPE)
    try:
        extend("L_SW", Watched)
        assert Watched not in {type(t) for t in SAMPLE_TERMS}
        test_every_term_type_has_a_sample_that_round_trips()
        assert build_sample(Watched) == Watched(name="xx", count=4, state=next(iter(SWState)))
    finally:
        LANGUAGES.clear()
        LANGUAGES.update(languages)
        base._BY_TYPE.clear()
        base._BY_TYPE.update(by_type)


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
