"""The FIPA ACL string representation of a communicate (FIPA SC00070), and human one-liners.

:func:`to_string` writes a :class:`Communicate` as the S-expression of FIPA SC00070 §2.1::

    (query-ref
     :sender (agent-identifier :name a_pl :addresses (sequence tcp/127.0.0.1:7447))
     :receiver (set (agent-identifier :name a_km))
     :content #23"<23 bytes>
     :language L_WM :encoding msgpack :protocol fipa-query :conversation-id c-ab12
     :reply-by 20261121T153000000Z :X-priority 2)

and :func:`parse` reads it back; ``parse(to_string(m)) == m`` for every communicate ``m``
whose ``reply_by`` is a whole number of milliseconds (see *Times* below).

Content bytes (SC00070 §2.3, ``String = StringLiteral | ByteLengthEncodedString``)
    * When the content is valid UTF-8 and contains no control character (Unicode category
      ``Cc``: U+0000–U+001F, U+007F–U+009F), it is written as a ``StringLiteral``: the text
      between double quotes, with ``"`` written ``\\"`` and ``\\`` written ``\\\\``. Parsing
      a ``StringLiteral`` gives back its text encoded as UTF-8.
    * Otherwise (in roco usually: msgpack content) it is written as a
      ``ByteLengthEncodedString`` ``#<n>"<n octets>``, where ``n`` is the decimal count of
      content bytes and the octets are the content bytes unchanged. Parsing one gives back
      exactly those ``n`` octets, whatever they are (no escapes, no terminator).

    Because :func:`to_string` returns ``str``, the octets of a byte-length-encoded string
    appear in it as the characters U+0000–U+00FF of the same value (ISO 8859-1), one
    character per byte, so ``n`` counts both. :func:`to_bytes` gives the octet stream of
    SC00070 proper: everything as UTF-8 except the octets of byte-length-encoded strings,
    which are raw. :func:`parse` accepts both: a ``str`` (octets as U+0000–U+00FF) or
    ``bytes`` (raw octets, the rest UTF-8). Both forms round-trip exactly.

    SC00070's ``StringLiteral`` has no escape for ``\\`` itself; roco writes ``\\\\`` and
    reads ``\\\\`` and ``\\"`` as escapes, any other backslash as itself.

Other parameters (SC00070 §2.1)
    Text-valued parameters (``:language``, ``:encoding``, ``:ontology``, ``:protocol``,
    ``:conversation-id``, ``:reply-with``, ``:in-reply-to``, user parameters, addresses) are
    written as a ``Word`` when they are a plain identifier (``[A-Za-z_][A-Za-z0-9_.+/:@-]*``),
    else as a ``StringLiteral``. On parsing, any ``Expression`` is accepted for them: a word,
    number or date-time gives its text, a string its value, a parenthesised expression its
    source text.

Times (SC00070 §2.3 ``DateTimeToken``)
    ``:reply-by`` is written in UTC as ``YYYYMMDDThhmmssmmmZ`` (milliseconds, type designator
    ``Z``) and is rounded to the nearest millisecond; parsing gives ``milliseconds / 1000``.
    Relative times (leading ``+``) and local times (no ``Z``) are rejected: roco is UTC only.

Agent identifiers (FIPA SC00023 §4, SC00070 §2.1 ``AgentIdentifier``)
    ``(agent-identifier :name <word> :addresses (sequence <url>*))``; ``:addresses`` is left
    out when empty. ``:resolvers`` and user parameters inside an agent identifier are rejected
    (roco's :class:`AgentIdentifier` has no place for them).

User-defined parameters (SC00061 §2.1, SC00070 §2.1)
    ``:X-name value`` for every entry of ``user_params``; the key is written as is and must
    therefore contain no white space (U+0000–U+0020) and no parenthesis.

Keywords (performative, parameter names, ``set``, ``sequence``, ``agent-identifier``) are
read case-insensitively; user parameter names keep their spelling and are told apart by it
(``:X-a`` and ``:x-a`` are two parameters, as they are two keys of ``user_params``).
"""

from __future__ import annotations

import base64
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import TypeVar

import msgspec

from shared.fipa_codec.acts import Performative
from shared.fipa_codec.aid import AgentIdentifier
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.message import Communicate

__all__ = [
    "MAX_STRING_FORM_SIZE",
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


class StringFormError(ValueError):
    """Text that is not a FIPA SC00070 string-form communicate roco can read.

    ``reason`` says what is wrong in one line; ``position`` is the offset of the problem in
    the input (a character offset for ``str`` input, a byte offset for ``bytes`` input).
    """

    def __init__(self, reason: str, position: int) -> None:
        super().__init__(f"{reason} (at position {position})")
        self.reason = reason
        self.position = position


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
    """A SC00070 ``StringLiteral`` for ``text`` (``\\`` and ``"`` escaped)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _word_or_literal(text: str) -> str:
    return text if _WORD.match(text) else _literal(text)


def _is_plain_text(data: bytes) -> str | None:
    """``data`` as text when it is UTF-8 without control characters, else None."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return None
    return None if _CONTROL.search(text) else text


def _content_pieces(data: bytes) -> list[_Piece]:
    text = _is_plain_text(data)
    if text is not None:
        return [_literal(text)]
    return [f'#{len(data)}"', bytes(data)]


def format_datetime(t: float) -> str:
    """POSIX time ``t`` (s, UTC) as a SC00070 §2.3 ``DateTimeToken``: ``YYYYMMDDThhmmssmmmZ``.

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


def _aid_pieces(agent: AgentIdentifier) -> str:
    out = f"(agent-identifier :name {_word_or_literal(agent.name)}"
    if agent.addresses:
        urls = " ".join(_word_or_literal(a) for a in agent.addresses)
        out += f" :addresses (sequence {urls})"
    return out + ")"


def _aid_set(agents: tuple[AgentIdentifier, ...]) -> str:
    return "(set " + " ".join(_aid_pieces(a) for a in agents) + ")"


def _human_content(msg: Communicate) -> str:
    rendered = content_as_json(msg)
    if rendered is not None:
        return _literal(rendered)
    text = _is_plain_text(msg.content)
    if text is not None:
        return _literal(text)
    return _literal(f"<{len(msg.content)} bytes, base64 {base64.b64encode(msg.content).decode()}>")


def _pieces(msg: Communicate, human: bool) -> list[list[_Piece]]:
    """The message as a list of parameters, each a list of pieces (first: the performative)."""
    params: list[list[_Piece]] = [[msg.performative.value]]

    def text(name: str, value: str | None) -> None:
        if value is not None:
            params.append([f":{name} {_word_or_literal(value)}"])

    if msg.sender is not None:
        params.append([":sender " + _aid_pieces(msg.sender)])
    if msg.receiver:
        params.append([":receiver " + _aid_set(msg.receiver)])
    if msg.content:
        if human:
            params.append([":content " + _human_content(msg)])
        else:
            params.append([":content ", *_content_pieces(msg.content)])
    text("language", msg.language)
    text("encoding", msg.encoding)
    text("ontology", msg.ontology)
    text("protocol", msg.protocol)
    text("conversation-id", msg.conversation_id)
    text("reply-with", msg.reply_with)
    text("in-reply-to", msg.in_reply_to)
    if msg.reply_by is not None:
        params.append([f":reply-by {format_datetime(msg.reply_by)}"])
    if msg.reply_to:
        params.append([":reply-to " + _aid_set(msg.reply_to)])
    for key, value in msg.user_params.items():
        if not key or _KEY_FORBIDDEN.search(key):
            raise ValueError(
                f"user parameter name {key!r} cannot be written in the string form: "
                "it must contain no white space and no parenthesis"
            )
        params.append([f":{key} {_word_or_literal(value)}"])
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

    Byte-length-encoded content appears as characters U+0000–U+00FF, one per octet (see the
    module docstring); ``parse(to_string(msg)) == msg`` (``reply_by`` rounded to the ms).
    ``pretty`` puts each parameter on its own line. ``human`` is a display-only form: content
    that decodes in its language is written as a string literal holding its JSON
    (:func:`content_as_json`), other binary content as ``"<n bytes, base64 …>"``; it is
    valid SC00070 but does not parse back to ``msg``.

    Raises ValueError when ``reply_by`` is not finite or outside the years 0001–9999, or a
    user parameter name contains white space or a parenthesis.
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
_BLE_HEAD = re.compile(r"#([0-9]{1,12})\"")
_DATETIME = re.compile(
    r"([+-])?([0-9]{4})([0-9]{2})([0-9]{2})[Tt]"  # sign, date
    r"([0-9]{2})([0-9]{2})([0-9]{2})([0-9]{3})([A-Za-z])?\Z"  # time, type designator
)


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str
    start: int
    end: int
    text: str = ""  # _STRING: the value; _ATOM: the text
    octets: bytes = b""  # _BYTES: the value


def _fix_text(raw: str, octets: bool, position: int) -> str:
    """Text scanned from the input: in octet mode ``raw`` holds UTF-8 octets as U+0000–U+00FF."""
    if not octets:
        return raw
    try:
        return raw.encode("latin-1").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StringFormError("invalid UTF-8", position + exc.start) from None


def _tokenize(src: str, octets: bool) -> list[_Token]:
    tokens: list[_Token] = []
    n = len(src)
    i = 0
    while i < n:
        c = src[i]
        if c <= " ":
            i += 1
        elif c == "(" or c == ")":
            tokens.append(_Token(c, i, i + 1))
            i += 1
        elif c == '"':
            chars: list[str] = []
            j = i + 1
            while True:
                k = j
                while k < n and src[k] != '"' and src[k] != "\\":
                    k += 1
                chars.append(src[j:k])
                if k >= n:
                    raise StringFormError("unterminated string literal", i)
                if src[k] == '"':
                    j = k + 1
                    break
                # a backslash: \" and \\ are escapes, any other backslash stands for itself
                if k + 1 < n and src[k + 1] in '"\\':
                    chars.append(src[k + 1])
                    j = k + 2
                else:
                    chars.append("\\")
                    j = k + 1
            tokens.append(_Token(_STRING, i, j, text=_fix_text("".join(chars), octets, i + 1)))
            i = j
        elif c == "#":
            m = _BLE_HEAD.match(src, i)
            if m is None:
                raise StringFormError("'#' must start a byte-length-encoded string #<digits>\"<octets>", i)
            length = int(m.group(1))
            begin = m.end()
            payload = src[begin : begin + length]
            if len(payload) < length:
                raise StringFormError(
                    f"byte-length-encoded string announces {length} octets but only {len(payload)} remain",
                    i,
                )
            try:
                value = payload.encode("latin-1")
            except UnicodeEncodeError as exc:
                raise StringFormError(
                    "a byte-length-encoded string in text holds one character U+0000-U+00FF per octet",
                    begin + exc.start,
                ) from None
            tokens.append(_Token(_BYTES, i, begin + length, octets=value))
            i = begin + length
        else:
            j = i + 1
            while j < n and src[j] > " " and src[j] != "(" and src[j] != ")":
                j += 1
            tokens.append(_Token(_ATOM, i, j, text=_fix_text(src[i:j], octets, i)))
            i = j
    return tokens


def parse_datetime(token: str, position: int = 0) -> float:
    """A SC00070 §2.3 ``DateTimeToken`` in UTC (``YYYYMMDDThhmmssmmmZ``) as POSIX seconds.

    Raises StringFormError (at ``position``) for anything else, including relative times
    (leading ``+``/``-``) and local times (no ``Z``).
    """
    m = _DATETIME.match(token)
    if m is None:
        raise StringFormError(f"{token!r} is not a date-time YYYYMMDDThhmmssmmmZ", position)
    sign, year, month, day, hour, minute, second, milli, designator = m.groups()
    if sign is not None:
        raise StringFormError(f"relative time {token!r} is not supported (UTC only)", position)
    if designator is None:
        raise StringFormError(f"local time {token!r} is not supported: end it in Z", position)
    if designator not in "Zz":
        raise StringFormError(f"time zone {designator!r} is not supported: use Z", position)
    try:
        dt = datetime(int(year), int(month), int(day), int(hour), int(minute), int(second), tzinfo=UTC)
    except ValueError as exc:
        raise StringFormError(f"invalid date-time {token!r}: {exc}", position) from None
    return ((dt - _EPOCH) // _ONE_MS + int(milli)) / 1000


class _Parser:
    def __init__(self, src: str, octets: bool) -> None:
        self.src = src
        self.octets = octets
        self.tokens = _tokenize(src, octets)
        self.i = 0

    # -- token helpers
    def peek(self) -> _Token | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def next(self, what: str) -> _Token:
        tok = self.peek()
        if tok is None:
            raise StringFormError(f"unexpected end of input: expected {what}", len(self.src))
        self.i += 1
        return tok

    def expect(self, kind: str, what: str) -> _Token:
        tok = self.next(what)
        if tok.kind != kind:
            raise StringFormError(f"expected {what}, found {self.describe(tok)}", tok.start)
        return tok

    def describe(self, tok: _Token) -> str:
        if tok.kind in (_LPAREN, _RPAREN):
            return f"'{tok.kind}'"
        if tok.kind == _ATOM:
            return f"{tok.text[:40]!r}"
        return "a string"

    def keyword(self, what: str) -> tuple[str, _Token]:
        tok = self.expect(_ATOM, what)
        return tok.text.lower(), tok

    # -- values
    def expression_text(self, what: str) -> str:
        """Any SC00070 Expression, as text (see module docstring)."""
        tok = self.next(what)
        if tok.kind == _ATOM:
            if tok.text.startswith(":"):
                raise StringFormError(f"expected {what}, found parameter {tok.text!r}", tok.start)
            return tok.text
        if tok.kind == _STRING:
            return tok.text
        if tok.kind == _BYTES:
            try:
                return tok.octets.decode("utf-8")
            except UnicodeDecodeError:
                raise StringFormError(f"{what} is not valid UTF-8", tok.start) from None
        if tok.kind == _RPAREN:
            raise StringFormError(f"expected {what}, found ')'", tok.start)
        depth = 1  # a parenthesised expression: its source text
        while depth:
            inner = self.next(f"')' closing the expression opened at {tok.start}")
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
        raise StringFormError(f":content must be a string, found {self.describe(tok)}", tok.start)

    def agent_identifier(self) -> AgentIdentifier:
        open_ = self.expect(_LPAREN, "'(agent-identifier'")
        head, tok = self.keyword("'agent-identifier'")
        if head != "agent-identifier":
            raise StringFormError(f"expected 'agent-identifier', found {tok.text!r}", tok.start)
        name: str | None = None
        addresses: tuple[str, ...] = ()
        seen: set[str] = set()
        while True:
            tok = self.next("')' or an agent-identifier parameter")
            if tok.kind == _RPAREN:
                break
            if tok.kind != _ATOM or not tok.text.startswith(":"):
                raise StringFormError(
                    f"expected an agent-identifier parameter, found {self.describe(tok)}",
                    tok.start,
                )
            param = tok.text.lower()
            if param in seen:
                raise StringFormError(f"agent-identifier parameter {tok.text} repeated", tok.start)
            seen.add(param)
            if param == ":name":
                name = self.expression_text("an agent name")
            elif param == ":addresses":
                addresses = tuple(self.sequence("sequence", self.url))
            else:
                raise StringFormError(
                    f"agent-identifier parameter {tok.text} is not supported (only :name and :addresses)",
                    tok.start,
                )
        if name is None:
            raise StringFormError("agent-identifier without :name", open_.start)
        try:
            return AgentIdentifier(name, addresses)
        except ValueError as exc:
            raise StringFormError(str(exc), open_.start) from None

    def url(self) -> str:
        return self.expression_text("an address")

    def sequence(self, head_word: str, item: Callable[[], _T]) -> list[_T]:
        self.expect(_LPAREN, f"'({head_word}'")
        head, tok = self.keyword(f"'{head_word}'")
        if head != head_word:
            raise StringFormError(f"expected '{head_word}', found {tok.text!r}", tok.start)
        items: list[_T] = []
        while True:
            tok_ = self.peek()
            if tok_ is None:
                raise StringFormError(f"unterminated ({head_word} …)", tok.start)
            if tok_.kind == _RPAREN:
                self.i += 1
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
            raise StringFormError(f"unknown performative {tok.text!r}", tok.start) from None
        sender: AgentIdentifier | None = None
        agents: dict[str, tuple[AgentIdentifier, ...]] = {}
        content = b""
        reply_by: float | None = None
        texts: dict[str, str] = {}
        user: dict[str, str] = {}
        seen: set[str] = set()
        while True:
            tok = self.next("')' closing the message or a message parameter")
            if tok.kind == _RPAREN:
                break
            if tok.kind != _ATOM or not tok.text.startswith(":"):
                raise StringFormError(
                    f"expected a message parameter ':name', found {self.describe(tok)}",
                    tok.start,
                )
            name = tok.text[1:]
            lname = name.lower()
            # FIPA names are case-insensitive; user parameter names are kept as written
            ident = name if lname.startswith("x-") else lname
            if ident in seen:
                raise StringFormError(f"message parameter {tok.text} repeated", tok.start)
            seen.add(ident)
            if lname.startswith("x-"):
                user[name] = self.expression_text(f"a value for {tok.text}")
            elif lname == "sender":
                sender = self.agent_identifier()
            elif lname in ("receiver", "reply-to"):
                agents[lname] = self.aid_set()
            elif lname == "content":
                content = self.content()
            elif lname == "reply-by":
                value = self.next("a date-time")
                if value.kind != _ATOM:
                    raise StringFormError(f"expected a date-time, found {self.describe(value)}", value.start)
                reply_by = parse_datetime(value.text, value.start)
            elif lname in _TEXT_PARAMS:
                texts[lname] = self.expression_text(f"a value for {tok.text}")
            else:
                raise StringFormError(f"unknown message parameter {tok.text}", tok.start)
        rest = self.peek()
        if rest is not None:
            raise StringFormError("text after the end of the message", rest.start)
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


def parse(text: str | bytes | bytearray | memoryview, *, max_size: int = MAX_STRING_FORM_SIZE) -> Communicate:
    """Read a communicate in the FIPA ACL string representation (FIPA SC00070 §2).

    ``text`` is either the ``str`` of :func:`to_string` (octets of byte-length-encoded
    strings as U+0000–U+00FF) or the octets of :func:`to_bytes` (UTF-8 elsewhere).
    Raises StringFormError, with the offset of the problem, for anything that is not one
    well-formed message: unknown performative or parameter, repeated parameter, bad
    agent name, malformed string or date-time, trailing text, input over ``max_size``.
    """
    if len(text) > max_size:
        raise StringFormError(f"input of {len(text)} exceeds the limit of {max_size}", max_size)
    if isinstance(text, str):
        try:
            text.encode("utf-8")
        except UnicodeEncodeError as exc:
            raise StringFormError("lone surrogate character", exc.start) from None
        return _Parser(text, octets=False).message()
    return _Parser(bytes(text).decode("latin-1"), octets=True).message()


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
