"""FIPA words, agent names, and the Zenoh key chunk that carries an agent name.

Words (FIPA SC00070 §2.3 lexical rules)
    ``Word = [~ "\\0x00" - "\\0x20", "(", ")", "#", "0" - "9", "-", "@"]
    [~ "\\0x00" - "\\0x20", "(", ")"]*``: a first character that is no white space
    (U+0000–U+0020), parenthesis, ``#``, digit, ``-`` or ``@``, then any characters but white
    space and parentheses. SC00070 types as words: an agent identifier's ``:name``, its
    addresses (``URL``), a message's ``:protocol`` and user-defined parameter names. Three
    readings are added here, each because the lexer could not tell the token from something
    else: a word may not start with ``"`` (it would open a ``StringLiteral``), may not be lexically
    a ``Number`` or a ``DateTime`` (``+1``, ``.5``, ``20261121T153000000Z``), and may not hold a
    lone surrogate (no UTF-8 for it). Any other character is allowed, non-ASCII included (JADE's
    lexer reads only ASCII words: ``ACLParser.jj`` ``WORD``, so a non-ASCII name reaches JADE
    as a parse error there).

Agent names (FIPA SC00023 §4, SC00070 §2.2)
    An agent name is a word of at most :data:`MAX_NAME_LENGTH` characters: roco's own agents
    (``a_co``, ``ag_ex``) as well as JADE's ``local@platform`` and default
    ``da0@host:1099/JADE``.

Key chunks (a key expression names channel, sender and receiver: services/runtime/keys.py)
    A Zenoh key chunk may not hold ``/``, ``*``, ``$``, ``?`` or ``#``, and one that starts
    with ``@`` is verbatim. :func:`key_chunk` maps a name to the chunk that carries it: the
    characters ``A–Z a–z 0–9 _ . - @ :`` stand for themselves, every other character is
    written as the ``%XX`` of each of its UTF-8 octets (upper-case hex), so
    ``da0@host:1099/JADE`` travels as ``da0@host:1099%2FJADE`` and a roco name (a letter,
    then letters, digits, ``_ . - @``) as itself. :func:`name_of_key_chunk` is its inverse and
    accepts only chunks :func:`key_chunk` writes (one chunk per name), so that two keys never
    carry the same agent.
"""

from __future__ import annotations

import re

__all__ = [
    "MAX_NAME_LENGTH",
    "check_agent_name",
    "check_word",
    "is_word",
    "key_chunk",
    "name_of_key_chunk",
]

MAX_NAME_LENGTH = 255
"""Longest agent name, in characters."""

# a first character that is no white space, ( ) # digit - @ " or surrogate; then no white space,
# parenthesis or surrogate
_WORD = re.compile(r'[^\x00-\x20()#0-9\-@"\ud800-\udfff][^\x00-\x20()\ud800-\udfff]*')
_NUMBER = re.compile(r"[+-]?([0-9]+|[0-9]+\.[0-9]*|[0-9]*\.[0-9]+)([eE][+-]?[0-9]+)?")
_DATETIME = re.compile(r"[+-]?[0-9]{8}[Tt][0-9]{9}[A-Za-z]?")
_ESCAPE = re.compile(r"[^A-Za-z0-9_.\-@:]")
_CHUNK = re.compile(r"(?:[A-Za-z0-9_.\-@:]|%[0-9A-F]{2})+")


KNOWN_MAX = 4096
"""Words, and agent names, found valid that are kept (a set each) so that the next check of the
same string is a set lookup: every communicate decoded checks its sender's and receivers' names
and its protocol, which are few and repeat. A process that meets more keeps checking the rest
with the regular expressions."""
KNOWN_WORDS: set[str] = set()
"""Words found valid (:func:`is_word`; at most :data:`KNOWN_MAX`): read outside this module
only, where a check must cost no call (shared/fipa_codec/message.py, aid.py)."""
KNOWN_NAMES: set[str] = set()
"""Agent names found valid (:func:`check_agent_name`), as :data:`KNOWN_WORDS`."""


def is_word(text: str) -> bool:
    """Whether ``text`` is a FIPA SC00070 ``Word`` (see the module docstring)."""
    if text in KNOWN_WORDS:
        return True
    if _WORD.fullmatch(text) is None:
        return False
    # a Number or DateTime that passes the first-character rule starts with + or .
    if text[0] in "+." and (_NUMBER.fullmatch(text) is not None or _DATETIME.fullmatch(text) is not None):
        return False
    if len(KNOWN_WORDS) < KNOWN_MAX:
        KNOWN_WORDS.add(text)
    return True


def check_word(text: object, what: str) -> str:
    """``text`` when it is a FIPA SC00070 ``Word``; else ValueError naming ``what`` (the
    field, e.g. ``":protocol"``) and the rule."""
    if type(text) is str and text in KNOWN_WORDS:  # the common case: a protocol decoded again
        return text
    if not isinstance(text, str) or not is_word(text):
        raise ValueError(
            f"invalid {what} {text!r}: not a FIPA SC00070 word (one must not be empty, hold white "
            'space or parentheses, start with # - @ " or a digit, or read as a number or date-time)'
        )
    return text


def check_agent_name(name: object) -> str:
    """``name`` when it is an agent name (a word of at most :data:`MAX_NAME_LENGTH`
    characters, FIPA SC00023 §4 / SC00070 §2.2); else ValueError saying why."""
    # the common case first: run on every agent identifier decoded
    if type(name) is str and name in KNOWN_NAMES:
        return name
    if (
        isinstance(name, str)
        and len(name) <= MAX_NAME_LENGTH
        and _WORD.fullmatch(name) is not None
        and name[0] not in "+."
    ):
        if type(name) is str and len(KNOWN_NAMES) < KNOWN_MAX:
            KNOWN_NAMES.add(name)
        return name
    check_word(name, "agent name")
    assert isinstance(name, str)
    if len(name) > MAX_NAME_LENGTH:
        raise ValueError(f"invalid agent name {name[:40]!r}…: longer than {MAX_NAME_LENGTH} characters")
    return name


def _escape(m: re.Match[str]) -> str:
    return "".join(f"%{octet:02X}" for octet in m.group(0).encode("utf-8"))


def key_chunk(name: str) -> str:
    """The Zenoh key chunk that carries agent ``name`` (see the module docstring): ``a_co``
    gives ``a_co``, ``da0@host:1099/JADE`` gives ``da0@host:1099%2FJADE``.

    Raises ValueError when ``name`` is no agent name (:func:`check_agent_name`): such a name
    has no chunk.
    """
    check_agent_name(name)
    return _ESCAPE.sub(_escape, name)


def name_of_key_chunk(chunk: str) -> str:
    """The agent name that :func:`key_chunk` maps to ``chunk``; the inverse of :func:`key_chunk`.

    Raises ValueError when ``chunk`` is not one :func:`key_chunk` writes: a character other than
    ``A–Z a–z 0–9 _ . - @ :`` and ``%XX`` (upper-case hex), an escape of a character that stands
    for itself, octets that are not UTF-8, or a name that is no agent name.
    """
    if not _CHUNK.fullmatch(chunk):
        raise ValueError(
            f"key chunk {chunk[:60]!r} does not carry an agent name: expected A-Z a-z 0-9 _ . - @ : "
            "and %XX escapes"
        )
    try:
        name = re.sub(
            r"(?:%[0-9A-F]{2})+",
            lambda m: bytes.fromhex(m.group(0).replace("%", "")).decode("utf-8"),
            chunk,
        )
    except UnicodeDecodeError:
        raise ValueError(f"key chunk {chunk[:60]!r}: its %XX escapes are not UTF-8") from None
    check_agent_name(name)
    if key_chunk(name) != chunk:
        raise ValueError(f"key chunk {chunk[:60]!r} is not written as key_chunk writes {name!r}")
    return name
