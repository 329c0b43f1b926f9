"""Which writing system a person's line is in, so that a line a_hi cannot read is named for what
it is ("That line is in Japanese script …") rather than called empty.

a_hi reads English only. A line with no letter of the Latin script is refused here, before any
parse, naming the script of most of its letters (Unicode's character names: "KATAKANA LETTER
KA" is Katakana) or, when it has no letter at all (emoji, digits, punctuation), saying so. A
line in another language written in Latin letters ("tráeme la taza") is not detected: its words
are refused as unknown (a simplification, docs/agents.md)."""

from __future__ import annotations

import unicodedata
from collections import Counter

SCRIPT_NAMES = {
    "CJK": "Chinese",
    "HIRAGANA": "Japanese",
    "KATAKANA": "Japanese",
    "HANGUL": "Korean",
    "CYRILLIC": "Cyrillic",
    "GREEK": "Greek",
    "ARABIC": "Arabic",
    "HEBREW": "Hebrew",
    "DEVANAGARI": "Devanagari",
    "THAI": "Thai",
}
"""The first word of a letter's Unicode name, as the script is said to the person."""


def _script(c: str) -> str:
    """The script of letter ``c``: the first word of its Unicode name ("LATIN", "KATAKANA", …);
    "OTHER" when it has none."""
    name = unicodedata.name(c, "")
    return name.split(" ", 1)[0] if name else "OTHER"


def unreadable(line: str) -> str | None:
    """Why a_hi cannot read ``line`` at all, as the start of one sentence for the person, or None
    when it has a Latin letter (then it is read). Looks at most the first 2,000 characters.

    >>> unreadable("カップを持ってきて")
    'That line is in Japanese script'
    >>> unreadable("🍵🍵") is None, unreadable("bring the cup") is None
    (False, True)
    """
    scripts: Counter[str] = Counter()
    for c in line[:2000]:
        if c.isalpha():
            script = _script(c)
            if script == "LATIN":
                return None
            scripts[script] += 1
    if not scripts:
        return "I heard no words in that line, only symbols" if line.strip() else None
    if scripts.keys() & {"HIRAGANA", "KATAKANA"}:  # kana among kanji: Japanese
        return "That line is in Japanese script"
    (most, _), *_ = scripts.most_common(1)
    return f"That line is in {SCRIPT_NAMES.get(most, most.title())} script"
