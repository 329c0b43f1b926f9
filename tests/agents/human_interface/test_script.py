"""A line a_hi cannot read is named for what it is (script.py), never called empty."""

from __future__ import annotations

import pytest

from services.agents.human_interface.language import NotUnderstood, default_vocabulary, interpret
from services.agents.human_interface.script import other_language, unreadable


@pytest.mark.parametrize(
    ("line", "said"),
    [
        ("カップを持ってきて", "That line is in Japanese script"),
        ("把杯子拿给我", "That line is in Chinese script"),
        ("컵 좀 가져다 줘", "That line is in Korean script"),
        ("принеси чашку", "That line is in Cyrillic script"),
        ("φέρε μου το φλιτζάνι", "That line is in Greek script"),
        ("أحضر الكوب", "That line is in Arabic script"),
        ("🍵🍵", "I heard no words in that line, only symbols"),
        ("?!", "I heard no words in that line, only symbols"),
    ],
)
def test_a_line_without_latin_letters_is_named(line: str, said: str) -> None:
    assert unreadable(line) == said


@pytest.mark.parametrize(
    "line", ["bring me the cup", "bring me the café cup", "bring me the カップ", "", "  "]
)
def test_a_line_with_a_latin_letter_is_read(line: str) -> None:
    assert unreadable(line) is None


def test_only_the_first_characters_are_looked_at() -> None:
    assert unreadable("カ" * 2000 + "bring me the cup") == "That line is in Japanese script"
    assert unreadable("カ" * 1999 + "b") is None


@pytest.mark.parametrize(
    ("line", "language"),
    [
        ("tráeme la taza", "Spanish"),
        ("Bitte gieß das Glas in die Schüssel", "German"),
        ("portami la tazza per favore", "Italian"),
        ("haal de beker", "Dutch"),
    ],
)
def test_a_line_in_another_language_in_latin_letters_is_named(line: str, language: str) -> None:
    with pytest.raises(NotUnderstood) as info:
        interpret(line, vocabulary=default_vocabulary())
    assert str(info.value).startswith(f"That looks like {language}; I understand English only")


@pytest.mark.parametrize("line", ["cook dinner", "blah blah blah", "bring me the spoon", "gimme da spoon"])
def test_english_a_hi_does_not_understand_is_not_called_another_language(line: str) -> None:
    """The planted fault of the check above: English (and nonsense) short lines, on which the
    identifier is unsure, keep their unknown words named."""
    with pytest.raises(NotUnderstood) as info:
        interpret(line, vocabulary=default_vocabulary())
    assert "looks like" not in str(info.value)
    assert other_language("naïve robot, bring the cup") is None
