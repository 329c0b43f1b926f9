"""Which writing system and language a person's line is in, so that a line a_hi cannot read is
named for what it is ("That line is in Japanese script …", "That looks like Spanish …") rather
than called empty or made of unknown words.

a_hi reads English only. A line with no letter of the Latin script is refused here, before any
parse, naming the script of most of its letters (Unicode's character names: "KATAKANA LETTER
KA" is Katakana) or, when it has no letter at all (emoji, digits, punctuation), saying so.

A line in Latin letters that a_hi did not understand, most of whose words it does not know, is
given to a language identifier (:func:`other_language`): py3langid (BSD licence; langid.py's
naive Bayes model over byte n-grams, shipped in its wheel, 4.5 MB; loading ≈ 0.7 s, at the first
such line, and 56 MB resident; a line ≈ 0.05 ms), asked among :data:`LANGUAGES` only. On short
lines it is unsure ("cook dinner": Norwegian 0.28; "blah blah blah": Indonesian 0.82), so a
language is named only when it is likely and not English, and either the line holds a letter
English does not use ("tráeme la taza": Spanish 0.51) or the language is near certain (≥
:data:`SURE`: "haal de beker", Dutch 0.97). Otherwise the line's unknown words are named, as
for any line."""

from __future__ import annotations

import functools
import threading
import unicodedata
from collections import Counter
from typing import Any

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


LANGUAGES = {
    "en": "English", "es": "Spanish", "de": "German", "fr": "French", "it": "Italian",
    "pt": "Portuguese", "nl": "Dutch", "pl": "Polish", "sv": "Swedish", "da": "Danish",
    "no": "Norwegian", "fi": "Finnish", "cs": "Czech", "sk": "Slovak", "hr": "Croatian",
    "tr": "Turkish", "ro": "Romanian", "hu": "Hungarian", "id": "Indonesian", "vi": "Vietnamese",
    "tl": "Tagalog", "sw": "Swahili",
}  # fmt: skip
"""The languages in Latin letters a line is compared with (ISO 639-1 code: name)."""
LIKELY = 0.5
"""The least probability at which a language with a letter English does not use is named."""
SURE = 0.9
"""The least probability at which a language is named from its words alone."""
MAX_CHARS = 2000
"""Of a longer line, the first this many characters are identified."""

_lock = threading.Lock()


@functools.cache
def _identifier() -> Any:
    """py3langid's identifier over :data:`LANGUAGES`, probabilities normalised, holding only
    their columns of the model (≈ 56 MB resident; the whole model, 76 MB, only while it loads).
    Loaded at the first line that needs it, not at a_hi's start. Raises ImportError when
    py3langid is not installed."""
    from py3langid.langid import MODEL_FILE, LanguageIdentifier

    whole = LanguageIdentifier.from_model_file(MODEL_FILE, norm_probs=True)
    whole.set_languages(list(LANGUAGES))
    return LanguageIdentifier(  # built anew from the restricted arrays: the whole model is freed
        whole.nb_ptc,
        whole.nb_pc,
        whole.nb_classes,
        whole.tk_nextmove,
        whole.tk_output,
        norm_probs=True,
        tk_row=whole.tk_row,
    )


def other_language(line: str) -> str | None:
    """The name of the language other than English ``line`` is likely in (module docstring),
    or None.

    >>> other_language("haal de beker"), other_language("bring me the cup")
    ('Dutch', None)
    """
    text = line[:MAX_CHARS]
    with _lock:
        identifier = _identifier()
    code, probability = identifier.classify(text)
    if code == "en" or probability < LIKELY:
        return None
    foreign_letter = any(c.isalpha() and not c.isascii() and _script(c) == "LATIN" for c in text)
    return LANGUAGES.get(code) if foreign_letter or probability >= SURE else None
