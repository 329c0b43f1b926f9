"""What a notice's content tells the person (shared/fipa_codec/languages/told.py): a term's own
``told()``, else its string form, at most a Notice's length."""

from __future__ import annotations

import msgspec
import pytest

from shared.fipa_codec.languages.l_hc import MAX_NOTICE_CHARS, Notice
from shared.fipa_codec.languages.told import CUT, told


class Says(msgspec.Struct, frozen=True):
    text: str

    def told(self) -> str:
        return f"it says {self.text}"


class Silent(msgspec.Struct, frozen=True):
    name: str


class Wrong(msgspec.Struct, frozen=True):
    def told(self) -> str:
        return 3  # type: ignore[return-value]


def test_a_notice_is_told_by_its_text() -> None:
    assert told(Notice(text="the jar tipped over")) == "the jar tipped over"


def test_a_term_that_says_itself_is_told_by_its_sentence() -> None:
    assert told(Says("hello")) == "it says hello"


def test_a_term_without_told_is_told_by_its_string_form() -> None:
    assert told(Silent("cup")) == "Silent(name='cup')"


@pytest.mark.parametrize("extra", [1, 1000])
def test_an_over_long_sentence_is_cut_to_a_notice_s_length(extra: int) -> None:
    said = told(Says("a" * MAX_NOTICE_CHARS))
    assert len(said) == MAX_NOTICE_CHARS and said.endswith(CUT)
    assert (
        told(Silent("b" * (MAX_NOTICE_CHARS + extra)))
        == str(Silent("b" * MAX_NOTICE_CHARS))[: MAX_NOTICE_CHARS - 1] + CUT
    )


def test_a_sentence_of_a_notice_s_length_is_whole() -> None:
    assert told(Notice(text="n" * MAX_NOTICE_CHARS)) == "n" * MAX_NOTICE_CHARS


def test_a_told_that_returns_no_str_is_refused() -> None:
    with pytest.raises(TypeError, match=r"Wrong.told\(\) returned int, not str"):
        told(Wrong())
