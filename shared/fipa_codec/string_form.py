"""The FIPA ACL string representation of a communicate (FIPA SC00070 §2.2), and human one-liners.

:func:`to_string` (``str``, octets of byte-length strings as U+0000–U+00FF) and :func:`to_bytes`
(SC00070's octet stream: UTF-8 but for those raw octets) write a :class:`Communicate` as
``(query-ref :sender (agent-identifier :name a_pl …) :receiver (set …) :content "…" …)``;
:func:`parse` reads either back, strictly, plus the two JADE 4.6 leniencies named in the
reference (``StringACLCodec``, ``ACLParser.jj``). ``parse(to_string(m)) == m`` for every
communicate whose ``reply_by`` is a whole number of milliseconds (``:reply-by`` is written in
UTC as ``YYYYMMDDThhmmssmmmZ``). Agent names and ``:protocol`` are SC00070 Words
(``shared/fipa_codec/names.py``); parameters are those of SC00061 §2, identifiers SC00023 §4.

Errors: :func:`parse` raises :class:`StringFormError` only (a ``ValueError`` naming what was
expected and its offset, line and column); :func:`to_string` / :func:`to_bytes` raise
``ValueError`` for a protocol that is no Word or a user parameter name with white space or a
parenthesis. The full grammar, string, time and agent-identifier rules: docs/string_form.md.
"""

from __future__ import annotations

import base64
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta, tzinfo
from typing import Literal, TypeVar

import msgspec

from shared.fipa_codec.acts import Performative
from shared.fipa_codec.aid import MAX_AID_DEPTH, AgentIdentifier
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.message import Communicate
from shared.fipa_codec.names import check_word, is_word

__all__ = [
    "MAX_AID_DEPTH",
    "MAX_STRING_FORM_SIZE",
    "MAX_STRING_FORM_TOKENS",
    "AidExtras",
    "StringFormError",
    "content_as_json",
    "format_datetime",
    "parse",
    "parse_datetime",
    "summary",
    "to_bytes",
    "to_string",
]

MAX_STRING_FORM_SIZE = 32 * 1024 * 1024
"""Largest input :func:`parse` accepts by default (characters or bytes)."""
MAX_STRING_FORM_TOKENS = 1 << 20
"""Most tokens (atoms, strings, parentheses) :func:`parse` reads by default."""

AidExtras = Literal["keep", "reject", "drop"]
"""What :func:`parse` does with ``:resolvers`` and user parameters of an agent identifier:
keep them (the default), reject them (StringFormError) or drop them."""


class StringFormError(ValueError):
    """Text that is not a FIPA SC00070 string-form communicate roco can read.

    ``reason`` says what is wrong in one line, usually ``expected …, found …``;
    ``position`` is the offset of the problem in the input (a character offset for ``str``
    input, a byte offset for ``bytes`` input); ``line`` and ``column`` (from 1; the column
    counts characters or bytes like ``position``) are set by :func:`parse`, else None.
    """

    def __init__(
        self, reason: str, position: int, line: int | None = None, column: int | None = None
    ) -> None:
        where = f"at position {position}"
        if line is not None and column is not None:
            where += f", line {line} column {column}"
        super().__init__(f"{reason} ({where})")
        self.reason = reason
        self.position = position
        self.line = line
        self.column = column


# ---------------------------------------------------------------------------------------------
# Writing

_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_.+/:@\-]*\Z")
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")
_KEY_FORBIDDEN = re.compile(r"[\x00-\x20()]")
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
_ONE_MS = timedelta(milliseconds=1)

# A piece of output: text, or the raw octets of a byte-length-encoded string.
_Piece = str | bytes


def _literal(text: str) -> str:
    """A SC00070 ``StringLiteral`` for ``text``: ``"`` escaped, nothing else. ``text`` must
    not end in a backslash (see :func:`_string_pieces`)."""
    return '"' + text.replace('"', '\\"') + '"'


def _as_text(data: bytes) -> str | None:
    """``data`` as text when it is UTF-8, else None."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def _is_plain_text(data: bytes) -> str | None:
    """``data`` as text when it is UTF-8 without control characters, else None (human forms)."""
    text = _as_text(data)
    return None if text is None or _CONTROL.search(text) else text


def _string_pieces(data: bytes) -> list[_Piece]:
    """``data`` as a SC00070 ``String``: a literal when it is text (UTF-8) not ending in a
    backslash, else byte-length encoded (docs/string_form.md, *Strings*)."""
    text = _as_text(data)
    if text is not None and not text.endswith("\\"):
        return [_literal(text)]
    return [f'#{len(data)}"', bytes(data)]


def _text_pieces(text: str) -> list[_Piece]:
    """A text value as a ``Word`` when it is a plain identifier, else as a ``String``."""
    return [text] if _WORD.match(text) else _string_pieces(text.encode("utf-8"))


def format_datetime(t: float) -> str:
    """POSIX time ``t`` (s, UTC) as a SC00070 §2.3 ``DateTime`` in UTC: ``YYYYMMDDThhmmssmmmZ``.

    Rounds to the nearest millisecond. Raises ValueError when ``t`` is not finite or falls
    outside the years 0001–9999.
    """
    if not math.isfinite(t):
        raise ValueError(f"time {t!r} is not finite")
    try:
        dt = _EPOCH + timedelta(milliseconds=round(t * 1000))
    except OverflowError:
        raise ValueError(f"time {t!r} is outside the years 0001-9999") from None
    return (
        f"{dt.year:04d}{dt.month:02d}{dt.day:02d}T"
        f"{dt.hour:02d}{dt.minute:02d}{dt.second:02d}{dt.microsecond // 1000:03d}Z"
    )


def _aid_pieces(agent: AgentIdentifier) -> list[_Piece]:
    """``agent`` as a SC00070 ``AgentIdentifier``: ``:name``, ``:addresses``, ``:resolvers``,
    then the user-defined parameters (the order of the grammar); empty sequences left out."""
    # name and addresses are SC00070 words, checked by AgentIdentifier: written as they are
    out: list[_Piece] = ["(agent-identifier :name ", agent.name]
    if agent.addresses:
        out.append(" :addresses (sequence")
        for address in agent.addresses:
            out.extend([" ", address])
        out.append(")")
    if agent.resolvers:
        out.append(" :resolvers (sequence")
        for resolver in agent.resolvers:
            out.extend([" ", *_aid_pieces(resolver)])
        out.append(")")
    for key, value in agent.user:  # names checked by AgentIdentifier: X- and a Word
        out.extend([f" :{key} ", *_text_pieces(value)])
    out.append(")")
    return out


def _aid_set(agents: tuple[AgentIdentifier, ...]) -> list[_Piece]:
    out: list[_Piece] = ["(set"]
    for agent in agents:
        out.extend([" ", *_aid_pieces(agent)])
    out.append(")")
    return out


def _human_content(msg: Communicate) -> list[_Piece]:
    rendered = content_as_json(msg)
    if rendered is not None:
        return _string_pieces(rendered.encode("utf-8"))
    if _is_plain_text(msg.content) is not None:
        return _string_pieces(msg.content)
    return [_literal(f"<{len(msg.content)} bytes, base64 {base64.b64encode(msg.content).decode()}>")]


def _check_user_key(key: str) -> None:
    if len(key) < 3 or key[:2] not in ("X-", "x-") or _KEY_FORBIDDEN.search(key):
        raise ValueError(
            f"user parameter name {key!r} cannot be written in the string form: "
            "it needs a name after 'X-' and must contain no white space and no parenthesis"
        )


def _pieces(msg: Communicate, human: bool) -> list[list[_Piece]]:
    """The message as a list of parameters, each a list of pieces (first: the performative)."""
    params: list[list[_Piece]] = [[msg.performative.value]]

    def text(name: str, value: str | None) -> None:
        if value is not None:
            params.append([f":{name} ", *_text_pieces(value)])

    if msg.sender is not None:
        params.append([":sender ", *_aid_pieces(msg.sender)])
    if msg.receiver:
        params.append([":receiver ", *_aid_set(msg.receiver)])
    if msg.content:
        body = _human_content(msg) if human else _string_pieces(msg.content)
        params.append([":content ", *body])
    text("language", msg.language)
    text("encoding", msg.encoding)
    text("ontology", msg.ontology)
    if msg.protocol is not None:  # SC00070 §2.2: ":protocol" Word
        params.append([":protocol ", check_word(msg.protocol, ":protocol")])
    text("conversation-id", msg.conversation_id)
    text("reply-with", msg.reply_with)
    text("in-reply-to", msg.in_reply_to)
    if msg.reply_by is not None:
        params.append([f":reply-by {format_datetime(msg.reply_by)}"])
    if msg.reply_to:
        params.append([":reply-to ", *_aid_set(msg.reply_to)])
    for key, value in msg.user_params.items():
        _check_user_key(key)
        params.append([f":{key} ", *_text_pieces(value)])
    return params


def _join(params: list[list[_Piece]], pretty: bool) -> list[_Piece]:
    sep = "\n " if pretty else " "
    out: list[_Piece] = ["("]
    for i, param in enumerate(params):
        if i:
            out.append(sep)
        out.extend(param)
    out.append(")")
    return out


def to_string(msg: Communicate, *, pretty: bool = False, human: bool = False) -> str:
    """``msg`` in the FIPA ACL string representation (FIPA SC00070 §2), as text.

    Byte-length-encoded strings appear as characters U+0000–U+00FF, one per octet (see
    docs/string_form.md); ``parse(to_string(msg)) == msg`` (``reply_by`` rounded to the ms).
    ``pretty`` puts each parameter on its own line. ``human`` is a display-only form: content
    that decodes in its language is written as a string holding its JSON
    (:func:`content_as_json`), other binary content as ``"<n bytes, base64 …>"``; it is
    valid SC00070 but does not parse back to ``msg``.

    Raises ValueError when ``reply_by`` is not finite or outside the years 0001–9999, when
    ``protocol`` is no SC00070 word (SC00070 §2.2 ``":protocol" Word``), or a user parameter
    name is ``X-`` alone or contains white space or a parenthesis.
    """
    out = []
    for piece in _join(_pieces(msg, human), pretty):
        out.append(piece.decode("latin-1") if isinstance(piece, bytes) else piece)
    return "".join(out)


def to_bytes(msg: Communicate, *, pretty: bool = False) -> bytes:
    """``msg`` in the FIPA ACL string representation (FIPA SC00070 §2) as an octet stream:
    UTF-8 text with the raw octets of byte-length-encoded strings; ``parse(to_bytes(msg))``
    gives ``msg`` back. Raises ValueError as :func:`to_string`."""
    out = []
    for piece in _join(_pieces(msg, False), pretty):
        out.append(piece if isinstance(piece, bytes) else piece.encode("utf-8"))
    return b"".join(out)


# ---------------------------------------------------------------------------------------------
# Reading

_T = TypeVar("_T")
_LPAREN, _RPAREN, _STRING, _BYTES, _ATOM = "(", ")", "string", "bytes", "atom"
# what an atom is lexically (SC00070 §2.3): a Word, a Number or a DateTime
_WORD_ATOM, _NUMBER_ATOM, _DATETIME_ATOM, _BAD_ATOM = "word", "number", "date-time", "bad"
_NUMBER_TOKEN = re.compile(r"[+-]?([0-9]+|[0-9]+\.[0-9]*|[0-9]*\.[0-9]+)([eE][+-]?[0-9]+)?\Z")
_DATETIME_TOKEN = re.compile(r"[+-]?[0-9]{8}[Tt][0-9]{9}[A-Za-z]?\Z")
_BLE_HEAD = re.compile(r"#([0-9]{1,12})\"")
_SPACE = re.compile(r"[\x00-\x20]*")
_ATOM_REST = re.compile(r"[^\x00-\x20()]*")
_CLOSING_QUOTE = re.compile(r'(?<!\\)"')
_DATETIME = re.compile(
    r"([+-])?([0-9]{4})([0-9]{2})([0-9]{2})[Tt]"  # sign, date
    r"([0-9]{2})([0-9]{2})([0-9]{2})([0-9]{3})([A-Za-z])?\Z"  # time, type designator
)
# a relative time, as JADE reads it: a year of 365 days, a month of 30 days
_REL_UNITS_MS = (365 * 86_400_000, 30 * 86_400_000, 86_400_000, 3_600_000, 60_000, 1000, 1)
_MIN_MS = (datetime(1, 1, 1, tzinfo=UTC) - _EPOCH) // _ONE_MS  # the times format_datetime writes
_MAX_MS = (datetime(9999, 12, 31, 23, 59, 59, 999000, tzinfo=UTC) - _EPOCH) // _ONE_MS
_MESSAGE_PARAMS = (
    ":sender :receiver :content :language :encoding :ontology :protocol :conversation-id "
    ":reply-with :in-reply-to :reply-by :reply-to"
)


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str
    start: int
    end: int
    text: str = ""  # _STRING: the value; _ATOM: the text
    octets: bytes = b""  # _BYTES: the value
    lexeme: str = ""  # _ATOM: _WORD_ATOM, _NUMBER_ATOM or _DATETIME_ATOM


@dataclass(slots=True)
class _ParsedAid:
    """An agent identifier as SC00070 writes it, before it becomes an AgentIdentifier."""

    start: int
    name: str | None = None
    addresses: tuple[str, ...] = ()
    resolvers: tuple[_ParsedAid, ...] = ()
    user_params: dict[str, str] = field(default_factory=dict)
    extra_at: int | None = None  # where the first non-empty :resolvers or user parameter stands

    def agent_identifier(self, extras: bool) -> AgentIdentifier:
        """The :class:`AgentIdentifier`, with resolvers and user parameters when ``extras``.
        Raises StringFormError where this (or a resolver) stands when it is not one."""
        assert self.name is not None
        resolvers = tuple(r.agent_identifier(True) for r in self.resolvers) if extras else ()
        user = tuple(self.user_params.items()) if extras else ()
        try:
            return AgentIdentifier(self.name, self.addresses, resolvers, user)
        except ValueError as exc:
            raise StringFormError(str(exc), self.start) from None


def _fix_text(raw: str, octets: bool, position: int) -> str:
    """Text scanned from the input: in octet mode ``raw`` holds UTF-8 octets as U+0000–U+00FF."""
    if not octets:
        return raw
    try:
        return raw.encode("latin-1").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StringFormError("invalid UTF-8", position + exc.start) from None


def _string_literal(src: str, i: int, octets: bool) -> _Token:
    """The ``StringLiteral`` opening at ``src[i]``: ``\\"`` is a quote, all else as it stands.

    JADE's leniency (docs/string_form.md, *JADE's leniencies*): when no quote closes the literal but it
    passed over ``\\"``, the last of those closes it, its backslash the literal's last character.
    The closing quote is found by a regular expression, in time linear in the literal's length.
    """
    m = _CLOSING_QUOTE.search(src, i + 1)
    if m is not None:
        k = m.start()
    else:
        k = src.rfind('"', i + 1)  # every later quote is escaped: JADE takes the last one
        if k < 0:
            raise StringFormError("unterminated string literal: expected a closing '\"'", i)
    text = src[i + 1 : k].replace('\\"', '"')
    return _Token(_STRING, i, k + 1, text=_fix_text(text, octets, i + 1))


def _atom(src: str, i: int, j: int, octets: bool) -> _Token:
    """The atom ``src[i:j]`` (no white space, no parenthesis, not opening a string): a Word,
    a Number or a DateTime of SC00070 §2.3, else a bad atom, which no reader accepts."""
    text = _fix_text(src[i:j], octets, i)
    if _DATETIME_TOKEN.match(text):
        lexeme = _DATETIME_ATOM
    elif _NUMBER_TOKEN.match(text):
        lexeme = _NUMBER_ATOM
    elif is_word(text):
        lexeme = _WORD_ATOM
    else:
        lexeme = _BAD_ATOM
    return _Token(_ATOM, i, j, text=text, lexeme=lexeme)


def _byte_length_string(src: str, i: int) -> _Token:
    m = _BLE_HEAD.match(src, i)
    if m is None:
        raise StringFormError("'#' must start a byte-length-encoded string: expected #<digits>\"<octets>", i)
    length = int(m.group(1))
    begin = m.end()
    payload = src[begin : begin + length]
    if len(payload) < length:
        raise StringFormError(
            f"byte-length-encoded string announces {length} octets but only {len(payload)} remain", i
        )
    try:
        value = payload.encode("latin-1")
    except UnicodeEncodeError as exc:
        raise StringFormError(
            "a byte-length-encoded string in text holds one character U+0000-U+00FF per octet",
            begin + exc.start,
        ) from None
    return _Token(_BYTES, i, begin + length, octets=value)


class _Lexer:
    """The tokens of ``src``, one at a time (SC00070 §2.3), so that a parser that stops at an
    error has done work only up to it. White space and atoms are scanned with regular
    expressions (linear, in C); more than ``max_tokens`` tokens is a StringFormError where the
    one over the limit starts."""

    __slots__ = ("_ahead", "count", "i", "max_tokens", "octets", "src")

    def __init__(self, src: str, octets: bool, max_tokens: int) -> None:
        self.src = src
        self.octets = octets
        self.max_tokens = max_tokens
        self.i = 0
        self.count = 0
        self._ahead: _Token | None = None

    def peek(self) -> _Token | None:
        """The next token, not consumed; None at the end of the input."""
        if self._ahead is None:
            self._ahead = self._scan()
        return self._ahead

    def take(self) -> _Token | None:
        """The next token, consumed; None at the end of the input."""
        tok = self.peek()
        self._ahead = None
        return tok

    def _scan(self) -> _Token | None:
        src = self.src
        space = _SPACE.match(src, self.i)
        assert space is not None  # a star matches everywhere
        i = space.end()
        if i >= len(src):
            self.i = i
            return None
        self.count += 1
        if self.count > self.max_tokens:
            raise StringFormError(f"more than {self.max_tokens} tokens", i)
        c = src[i]
        if c == "(" or c == ")":
            tok = _Token(c, i, i + 1)
        elif c == '"':
            tok = _string_literal(src, i, self.octets)
        elif c == "#":
            tok = _byte_length_string(src, i)
        else:
            rest = _ATOM_REST.match(src, i + 1)
            assert rest is not None  # a star matches everywhere
            tok = _atom(src, i, rest.end(), self.octets)
        self.i = tok.end
        return tok


def parse_datetime(
    token: str, position: int = 0, *, now: float | None = None, tz: tzinfo | None = None
) -> float:
    """A SC00070 §2.3 ``DateTime`` token as POSIX seconds (docs/string_form.md, *Times*).

    ``YYYYMMDDThhmmssmmmZ`` is UTC; without the ``Z`` the time is local to ``tz`` (default:
    this machine's time zone); with a leading ``+``/``-`` it is a duration after/before
    ``now`` (POSIX seconds, default: the current time), with years of 365 days and months
    of 30 days, rounded to the millisecond. Raises StringFormError (at ``position``) for
    anything else: a malformed token, an impossible date, a type designator other than
    ``Z``, a time outside the years 0001–9999 (UTC), which :func:`format_datetime` could not
    write back.
    """
    m = _DATETIME.match(token)
    if m is None:
        raise StringFormError(
            f"expected a date-time [+|-]YYYYMMDDThhmmssmmm[Z], found {token[:40]!r}", position
        )
    sign, *digits, designator = m.groups()
    if designator is not None and designator not in "Zz":
        raise StringFormError(
            f"time zone designator {designator!r} in {token!r} is not supported: expected Z (UTC) or none",
            position,
        )
    fields = [int(d) for d in digits]
    if sign is not None:
        duration_ms = sum(f * unit for f, unit in zip(fields, _REL_UNITS_MS, strict=True))
        base = time.time() if now is None else now
        ms = round(base * 1000 + (duration_ms if sign == "+" else -duration_ms))
    else:
        year, month, day, hour, minute, second, milli = fields
        try:
            dt = datetime(year, month, day, hour, minute, second)
            if designator is not None:
                aware = dt.replace(tzinfo=UTC)
            elif tz is not None:
                aware = dt.replace(tzinfo=tz)
            else:
                aware = dt.astimezone()  # a naive time is this machine's local time
            ms = (aware - _EPOCH) // _ONE_MS + milli
        except (ValueError, OverflowError, OSError) as exc:
            raise StringFormError(f"invalid date-time {token!r}: {exc}", position) from None
    if not _MIN_MS <= ms <= _MAX_MS:
        raise StringFormError(f"invalid date-time {token!r}: outside the years 0001-9999 (UTC)", position)
    return ms / 1000


class _Parser:
    def __init__(
        self,
        src: str,
        octets: bool,
        now: float | None,
        tz: tzinfo | None,
        aid_extras: AidExtras,
        max_tokens: int,
    ) -> None:
        self.src = src
        self.octets = octets
        self.now = time.time() if now is None else now
        self.tz = tz
        self.aid_extras = aid_extras
        self.lexer = _Lexer(src, octets, max_tokens)

    # -- token helpers
    def peek(self) -> _Token | None:
        return self.lexer.peek()

    def next(self, what: str) -> _Token:
        tok = self.lexer.take()
        if tok is None:
            raise StringFormError(f"unexpected end of input: expected {what}", len(self.src))
        return tok

    def expect(self, kind: str, what: str) -> _Token:
        tok = self.next(what)
        if tok.kind != kind:
            raise StringFormError(f"expected {what}, found {self.describe(tok)}", tok.start)
        return tok

    @staticmethod
    def describe(tok: _Token) -> str:
        if tok.kind in (_LPAREN, _RPAREN):
            return f"'{tok.kind}'"
        if tok.kind == _ATOM:
            if tok.lexeme == _BAD_ATOM:
                return (
                    f"{tok.text[:40]!r}, which is no SC00070 word, number or date-time "
                    "(a word does not start with a digit, '-' or '@')"
                )
            return f"{tok.lexeme} {tok.text[:40]!r}" if tok.lexeme != _WORD_ATOM else f"{tok.text[:40]!r}"
        return "a string"

    def word(self, what: str) -> str:
        """A SC00070 ``Word`` (:name, an address, :protocol); anything else is an error."""
        tok = self.next(what)
        if tok.kind != _ATOM or tok.lexeme != _WORD_ATOM:
            raise StringFormError(f"expected {what} (a SC00070 word), found {self.describe(tok)}", tok.start)
        return tok.text

    def keyword(self, what: str) -> tuple[str, _Token]:
        tok = self.expect(_ATOM, what)
        return tok.text.lower(), tok

    def parameter_name(self, what: str) -> _Token | None:
        """The next ``:name`` token, or None (consumed) at the closing parenthesis."""
        tok = self.next(f"')' or {what}")
        if tok.kind == _RPAREN:
            return None
        if tok.kind != _ATOM or not tok.text.startswith(":"):
            raise StringFormError(f"expected ')' or {what}, found {self.describe(tok)}", tok.start)
        return tok

    # -- values
    def expression_text(self, what: str) -> str:
        """Any SC00070 Expression, as text (docs/string_form.md, *Parameters*)."""
        tok = self.next(what)
        if tok.kind == _ATOM:
            if tok.text.startswith(":"):
                raise StringFormError(f"expected {what}, found parameter {tok.text!r}", tok.start)
            if tok.lexeme == _BAD_ATOM:
                raise StringFormError(f"expected {what}, found {self.describe(tok)}", tok.start)
            return tok.text
        if tok.kind == _STRING:
            return tok.text
        if tok.kind == _BYTES:
            try:
                return tok.octets.decode("utf-8")
            except UnicodeDecodeError:
                raise StringFormError(f"expected {what} in UTF-8, found invalid UTF-8", tok.start) from None
        if tok.kind == _RPAREN:
            raise StringFormError(f"expected {what}, found ')'", tok.start)
        depth = 1  # a parenthesised expression: its source text
        while depth:
            inner = self.next(f"')' closing the expression opened at {tok.start}")
            if inner.kind == _ATOM and inner.lexeme == _BAD_ATOM:
                raise StringFormError(f"expected an expression, found {self.describe(inner)}", inner.start)
            if inner.kind == _LPAREN:
                depth += 1
            elif inner.kind == _RPAREN:
                depth -= 1
        return _fix_text(self.src[tok.start : inner.end], self.octets, tok.start)

    def content(self) -> bytes:
        tok = self.next("a string")
        if tok.kind == _STRING:
            return tok.text.encode("utf-8")
        if tok.kind == _BYTES:
            return tok.octets
        if tok.kind == _ATOM and tok.lexeme == _WORD_ATOM and not tok.text.startswith(":"):
            return tok.text.encode("utf-8")  # a Word, as JADE accepts (ACLParser.jj Content())
        raise StringFormError(f"expected a string after :content, found {self.describe(tok)}", tok.start)

    def user_parameter(self, tok: _Token) -> str:
        if len(tok.text) < 4:
            raise StringFormError(
                f"expected a name after {tok.text!r} in a user-defined parameter", tok.start
            )
        return self.expression_text(f"a value for {tok.text}")

    def parsed_aid(self, depth: int) -> _ParsedAid:
        open_ = self.expect(_LPAREN, "'(agent-identifier'")
        if depth > MAX_AID_DEPTH:
            raise StringFormError(f"agent identifiers nested deeper than {MAX_AID_DEPTH}", open_.start)
        head, tok = self.keyword("'agent-identifier'")
        if head != "agent-identifier":
            raise StringFormError(f"expected 'agent-identifier', found {tok.text[:40]!r}", tok.start)
        aid = _ParsedAid(open_.start)
        seen: set[str] = set()
        while (tok_ := self.parameter_name("an agent-identifier parameter")) is not None:
            param = tok_.text.lower()
            ident = tok_.text if param.startswith(":x-") else param
            if ident in seen:
                raise StringFormError(f"agent-identifier parameter {tok_.text} repeated", tok_.start)
            seen.add(ident)
            if param == ":name":
                aid.name = self.word("an agent name")
            elif param == ":addresses":
                aid.addresses = tuple(self.sequence("sequence", self.url))
            elif param == ":resolvers":
                aid.resolvers = tuple(self.sequence("sequence", lambda: self.parsed_aid(depth + 1)))
                if aid.resolvers and aid.extra_at is None:
                    aid.extra_at = tok_.start
            elif param.startswith(":x-"):
                aid.user_params[tok_.text[1:]] = self.user_parameter(tok_)
                if aid.extra_at is None:
                    aid.extra_at = tok_.start
            else:
                raise StringFormError(
                    f"unknown agent-identifier parameter {tok_.text}: expected :name, :addresses, "
                    ":resolvers or a user-defined :X-name",
                    tok_.start,
                )
        if aid.name is None:
            raise StringFormError("agent-identifier without :name: expected ':name <word>'", open_.start)
        return aid

    def agent_identifier(self) -> AgentIdentifier:
        parsed = self.parsed_aid(1)
        if parsed.extra_at is not None and self.aid_extras == "reject":
            raise StringFormError(
                "agent-identifier with :resolvers or user-defined parameters, "
                "rejected as asked (aid_extras='reject')",
                parsed.extra_at,
            )
        return parsed.agent_identifier(self.aid_extras == "keep")

    def url(self) -> str:
        return self.word("an address")

    def sequence(self, head_word: str, item: Callable[[], _T]) -> list[_T]:
        self.expect(_LPAREN, f"'({head_word}'")
        head, tok = self.keyword(f"'{head_word}'")
        if head != head_word:
            raise StringFormError(f"expected '{head_word}', found {tok.text[:40]!r}", tok.start)
        items: list[_T] = []
        while True:
            tok_ = self.peek()
            if tok_ is None:
                raise StringFormError(f"unterminated ({head_word} …): expected ')'", tok.start)
            if tok_.kind == _RPAREN:
                self.lexer.take()
                return items
            items.append(item())

    def aid_set(self) -> tuple[AgentIdentifier, ...]:
        return tuple(self.sequence("set", self.agent_identifier))

    # -- the message
    def message(self) -> Communicate:
        self.expect(_LPAREN, "'(' opening the message")
        perf_text, tok = self.keyword("a performative")
        try:
            performative = Performative(perf_text)
        except ValueError:
            raise StringFormError(
                f"unknown performative {tok.text[:40]!r}: expected one of the 22 of FIPA SC00037 "
                "(accept-proposal, agree, … subscribe)",
                tok.start,
            ) from None
        sender: AgentIdentifier | None = None
        agents: dict[str, tuple[AgentIdentifier, ...]] = {}
        content = b""
        reply_by: float | None = None
        texts: dict[str, str] = {}
        user: dict[str, str] = {}
        seen: set[str] = set()
        while (tok_ := self.parameter_name("a message parameter ':name'")) is not None:
            name = tok_.text[1:]
            lname = name.lower()
            # FIPA names are case-insensitive; user parameter names are kept as written
            ident = name if lname.startswith("x-") else lname
            if ident in seen:
                raise StringFormError(f"message parameter {tok_.text} repeated", tok_.start)
            seen.add(ident)
            if lname.startswith("x-"):
                user[name] = self.user_parameter(tok_)
            elif lname == "sender":
                sender = self.agent_identifier()
            elif lname in ("receiver", "reply-to"):
                agents[lname] = self.aid_set()
            elif lname == "content":
                content = self.content()
            elif lname == "reply-by":
                value = self.next("a date-time")
                if value.kind != _ATOM or value.lexeme != _DATETIME_ATOM:
                    raise StringFormError(f"expected a date-time, found {self.describe(value)}", value.start)
                reply_by = parse_datetime(value.text, value.start, now=self.now, tz=self.tz)
            elif lname == "protocol":
                texts[lname] = self.word(f"a value for {tok_.text}")
            elif lname in _TEXT_PARAMS:
                texts[lname] = self.expression_text(f"a value for {tok_.text}")
            else:
                raise StringFormError(
                    f"unknown message parameter {tok_.text}: expected one of {_MESSAGE_PARAMS} "
                    "or a user-defined :X-name",
                    tok_.start,
                )
        rest = self.peek()
        if rest is not None:
            raise StringFormError("text after the end of the message: expected nothing", rest.start)
        return Communicate(
            performative=performative,
            sender=sender,
            receiver=agents.get("receiver", ()),
            reply_to=agents.get("reply-to", ()),
            content=content,
            language=texts.get("language"),
            encoding=texts.get("encoding"),
            ontology=texts.get("ontology"),
            protocol=texts.get("protocol"),
            conversation_id=texts.get("conversation-id"),
            reply_with=texts.get("reply-with"),
            in_reply_to=texts.get("in-reply-to"),
            reply_by=reply_by,
            user_params=user,
        )


_TEXT_PARAMS = frozenset(
    {
        "language",
        "encoding",
        "ontology",
        "protocol",
        "conversation-id",
        "reply-with",
        "in-reply-to",
    }
)


def _located(exc: StringFormError, src: str) -> StringFormError:
    """``exc`` with the line and column of its position in ``src``."""
    pos = min(max(exc.position, 0), len(src))
    line = src.count("\n", 0, pos) + 1
    column = pos - (src.rfind("\n", 0, pos) + 1) + 1
    return StringFormError(exc.reason, exc.position, line, column)


def parse(
    text: str | bytes | bytearray | memoryview,
    *,
    max_size: int = MAX_STRING_FORM_SIZE,
    max_tokens: int = MAX_STRING_FORM_TOKENS,
    now: float | None = None,
    tz: tzinfo | None = None,
    aid_extras: AidExtras = "keep",
) -> Communicate:
    """Read a communicate in the FIPA ACL string representation (FIPA SC00070 §2).

    ``text`` is either the ``str`` of :func:`to_string` (octets of byte-length-encoded
    strings as U+0000–U+00FF) or the octets of :func:`to_bytes` (UTF-8 elsewhere); any
    SC00070 message is read, keywords in any case. ``now`` (POSIX seconds, default: the
    time of the call) anchors a relative ``:reply-by``; ``tz`` (default: this machine's
    zone) places a local one. ``aid_extras`` says what happens to the ``:resolvers`` and
    user-defined parameters of an agent identifier: ``"keep"`` them (the default: they are
    read into :class:`AgentIdentifier`), ``"reject"`` the message (StringFormError where
    the first stands) or ``"drop"`` them.

    Raises ValueError for an unknown ``aid_extras``, and StringFormError, with the offset,
    line and column of the problem and what was expected there, for anything that is not
    one well-formed message: unknown performative or parameter, repeated parameter, an atom
    that is no word, number or date-time, anything but a word after ``:name``,
    ``:protocol`` or in ``:addresses`` (resolvers' included), agent identifiers nested
    deeper than :data:`MAX_AID_DEPTH`, malformed string or date-time, trailing text, input
    over ``max_size`` (characters or octets: refused before anything is read) or holding more
    than ``max_tokens`` tokens (atoms, strings, parentheses: refused where the one over the
    limit starts; the input is read token by token, so the work done is bounded by the limits,
    not by the input). JADE's leniencies (docs/string_form.md) are read, not refused.
    """
    if aid_extras not in ("keep", "reject", "drop"):
        raise ValueError(f"aid_extras must be 'keep', 'reject' or 'drop', not {aid_extras!r}")
    if len(text) > max_size:
        raise StringFormError(f"input of {len(text)} exceeds the limit of {max_size}", max_size)
    if isinstance(text, str):
        try:
            text.encode("utf-8")
        except UnicodeEncodeError as exc:
            raise _located(StringFormError("lone surrogate character", exc.start), text) from None
        src, octets = text, False
    else:
        src, octets = bytes(text).decode("latin-1"), True
    try:
        return _Parser(src, octets, now, tz, aid_extras, max_tokens).message()
    except StringFormError as exc:
        raise _located(exc, src) from None


# ---------------------------------------------------------------------------------------------
# Human forms


def content_as_json(msg: Communicate) -> str | None:
    """``msg``'s content decoded in its content language (``msg.language``, see
    ``shared.fipa_codec.languages``) and rendered as compact JSON (msgspec.json).

    None when there is no content, the ``encoding`` is neither absent nor ``msgpack``, the
    language is unknown, or the content is not a term of the language.
    """
    if not msg.content or msg.encoding not in (None, "msgpack"):
        return None
    try:
        term = decode_content(msg.language, msg.content)
    except ContentError:
        return None
    return msgspec.json.encode(term).decode("utf-8")


_ESCAPES = {c: f"\\x{c:02x}" for c in [*range(0x20), *range(0x7F, 0xA0)]}
_ESCAPES.update({ord("\n"): "\\n", ord("\r"): "\\r", ord("\t"): "\\t"})


def _one_line(text: str, limit: int | None) -> str:
    text = text.translate(_ESCAPES)
    if limit is not None and len(text) > limit:
        return text[: max(limit - 1, 0)] + "…"
    return text


def summary(msg: Communicate, content_text: str | None = None, *, max_content: int | None = 240) -> str:
    """A one-line human form of ``msg`` for terminal sniffers (not a FIPA format), e.g.::

        a_pl → a_km  query-ref  [fipa-query c=ab12…]  L_WM  {"type":"object","name":"jar"}

    Sender → receivers, performative, [protocol and the first 4 characters of the
    conversation-id], language, then the content: ``content_text`` when given, else the
    content as compact JSON when it decodes in its language (:func:`content_as_json`), else
    ``<n bytes>``. Control characters are escaped; the content is cut to ``max_content``
    characters (None: no limit).
    """
    sender = msg.sender.name if msg.sender is not None else "?"
    receivers = ",".join(r.name for r in msg.receiver) or "?"
    parts = [f"{sender} → {receivers}", msg.performative.value]
    tags = []
    if msg.protocol:
        tags.append(_one_line(msg.protocol, 40))
    if msg.conversation_id:
        cid = msg.conversation_id
        tags.append("c=" + _one_line(cid if len(cid) <= 4 else cid[:4] + "…", None))
    if tags:
        parts.append("[" + " ".join(tags) + "]")
    if msg.language:
        parts.append(_one_line(msg.language, 40))
    body = content_text if content_text is not None else content_as_json(msg)
    if body is None and msg.content:
        body = f"<{len(msg.content)} bytes>"
    if body:
        parts.append(_one_line(body, max_content))
    return "  ".join(parts)
