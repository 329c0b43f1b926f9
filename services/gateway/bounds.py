"""How much the gateway reads, waits and sends for one peer: every limit in one place
(:class:`Limits`), and the small checks that apply them before any work proportional to the
input is done (numbers by their digits, JSON by its depth, payload encodings by an allow-list).

Each limit is answered with one line: the HTTP status (FIPA SC00084 has only 200 and 406; the
others are HTTP's) or a FIPA refusal, as docs/gateway.md lists them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = [
    "DEFAULT_LIMITS",
    "ENCODINGS",
    "BoundError",
    "Limits",
    "decode_payload",
    "json_too_deep",
    "read_digits",
]


class BoundError(ValueError):
    """Input over one of the gateway's limits, or not of the form a limit is checked on; the
    message says which, in one line."""


@dataclass(frozen=True)
class Limits:
    """The gateway's limits (sizes in octets, times in seconds, counts), each with its default.

    The HTTP server (services/gateway/server.py) and the readers of the body, the envelope
    (FIPA SC00085) and the payload (FIPA SC00070) apply the ``max_*`` sizes and counts before
    doing work proportional to the input; the posting side (services/gateway/poster.py) the
    ``post_*`` ones; the gateway (services/gateway/bridge.py) the rest."""

    # ---- HTTP server
    backlog: int = 1024
    """Connections the kernel queues before the server accepts them (``listen`` backlog;
    Linux caps it at ``net.core.somaxconn``)."""
    max_connections: int = 1024
    """Connections open at once; one more is answered 503 and closed."""
    header_s: float = 10.0
    """From a connection's accept to the end of its request's headers; then 408 and closed."""
    request_s: float = 30.0
    """From the end of the headers to the whole body read; then 408 and closed."""
    max_line: int = 8190
    """The request line (JADE writes the whole URL there), and the request target with it."""
    max_header: int = 4096
    """One header field, name and value."""
    max_headers: int = 32
    """Header fields of one request."""
    max_body: int = 8 * 1024 * 1024
    """A body (``Content-Length``); a larger one is answered 413 and not read."""
    max_buffered: int = 64 * 1024 * 1024
    """Bodies held by all requests at once while they are read and parsed; a request that would
    go over is answered 503."""
    readers: int = 2
    """Threads reading bodies (multipart, XML, string form) and handing them to the gateway."""
    max_pending: int = 512
    """Messages read but not yet handled by the gateway's thread; one more is answered 503."""

    # ---- the body (FIPA SC00084), the envelope (FIPA SC00085) and the payload (FIPA SC00070)
    max_part_headers: int = 8192
    """The header block of one MIME part of the body."""
    max_envelope: int = 64 * 1024
    """The XML envelope part."""
    max_digits: int = 12
    """Digits of a number read from the input (``Content-Length``, ``payload-length``,
    ``params index``): a terabyte and more is refused, not parsed."""
    max_receivers: int = 8
    """Receivers (``to`` or ``intended-receiver``) of one envelope; each may cost an answer."""
    max_tokens: int = 10_000
    """Tokens (atoms, strings, parentheses) of the ACL payload in the string form."""

    # ---- what the gateway reads of the ACL message
    max_content: int = 64 * 1024
    """The content of a message (the JSON of a term); a larger one is not-understood."""
    max_json_depth: int = 32
    """Arrays and objects nested in the content's JSON; deeper is not-understood."""

    # ---- answers: where and how they are posted
    max_answer_addresses: int = 4
    """Addresses an answer is tried at, in the order given (the rest are not used)."""
    max_address: int = 2048
    """Characters of one answer address; a longer one is not used."""
    post_connect_s: float = 3.0
    """Connecting to an answer address, at most."""
    post_s: float = 10.0
    """One post, from connecting to the status line of the receiver's answer."""
    max_posts: int = 16
    """Posts under way at once (the client's connection pool)."""
    max_queued_posts: int = 256
    """Answers waiting for a free post; one more is dropped and counted ``post_dropped``."""

    # ---- foreign names
    max_names: int = 1024
    """Foreign names bound to a peer at once (services/gateway/identity.py)."""
    max_conversations: int = 256
    """Conversations kept open per foreign name; a new one beyond them ends the oldest."""
    conversation_s: float = 3600.0
    """A foreign agent's conversation unanswered this long is taken as ended."""
    linger_s: float = 60.0
    """A name stays bound this long after its last conversation ended."""

    # ---- conversations followed through their protocol (services/gateway/conversations.py)
    max_followed: int = 4096
    """Open conversations whose protocol state the gateway follows, all foreign names together;
    one more forgets the oldest (an answer in it is then dropped, ``dropped.out_of_protocol``).
    Four times what one agent follows (``ProtocolStates.max_open``, 1024): the conversations
    a_hi still follows are among them."""
    max_followed_ended: int = 1024
    """Ended conversations kept for what crosses their end on the wire (a late cancel, FIPA
    SC00026 §2) and to refuse what comes after it; the oldest beyond are forgotten."""


DEFAULT_LIMITS = Limits()
"""The limits ``roco gateway`` runs with."""


ENCODINGS: dict[str, str] = {
    "us-ascii": "ascii",
    "ascii": "ascii",
    "utf-8": "utf-8",
    "utf8": "utf-8",
    "iso-8859-1": "latin-1",
    "iso8859-1": "latin-1",
    "latin-1": "latin-1",
    "latin1": "latin-1",
    "iso-8859-15": "iso8859-15",
    "windows-1252": "cp1252",
    "cp1252": "cp1252",
    "utf-16": "utf-16",
    "utf-16le": "utf-16-le",
    "utf-16be": "utf-16-be",
}
"""The envelope's ``payload-encoding`` values the gateway reads (lower case) → Python's codec:
character sets decoded in linear time. Any other is refused (406), whatever Python knows."""

_DIGITS = re.compile(r"[0-9]+")


def read_digits(text: str, what: str, max_digits: int) -> int:
    """``text`` (surrounding white space allowed) as a non-negative decimal number of at most
    ``max_digits`` digits. Raises BoundError naming ``what`` when it is not one (the text is
    quoted, cut to 40 characters)."""
    digits = text.strip()
    if _DIGITS.fullmatch(digits) is None:
        raise BoundError(f"{what} {digits[:40]!r} is not a number")
    if len(digits) > max_digits:
        raise BoundError(f"{what} has {len(digits)} digits (at most {max_digits})")
    return int(digits)


_JSON_STRUCTURE = re.compile(rb'[\[\]{}"\\]')


def json_too_deep(data: bytes, limit: int) -> bool:
    """Whether the JSON text ``data`` nests arrays and objects deeper than ``limit`` (brackets
    inside strings are not counted). Linear in ``len(data)``; does not check that ``data`` is
    JSON (the decoder does, once this says it may)."""
    depth = 0
    in_string = False
    escaped = False
    for m in _JSON_STRUCTURE.finditer(data):
        c = m.group()
        if in_string:
            in_string, escaped = _in_string(c, data[m.end() : m.end() + 1], escaped)
        elif c == b'"':
            in_string = True
        else:
            step = _NESTING.get(c, 0)  # a backslash outside strings: not JSON, left to the decoder
            depth += step
            if step > 0 and depth > limit:
                return True
    return False


_NESTING = {b"[": 1, b"{": 1, b"]": -1, b"}": -1}
"""How a bracket outside strings changes the depth (the depth is checked as it grows)."""


def _in_string(c: bytes, after: bytes, escaped: bool) -> tuple[bool, bool]:
    """One structural character ``c`` inside a string (``after``: the byte after it; ``escaped``:
    ``c`` is escaped): whether the string goes on, and whether the next one is escaped."""
    if escaped:
        return True, False
    if c == b"\\":
        return True, after in b'\\"'  # \\ and \" escape the next one
    return c != b'"', False


def decode_payload(payload: bytes, encoding: str | None) -> str | bytes:
    """The ACL payload as the string form reader takes it: the octets themselves when the
    envelope's ``payload-encoding`` is absent, US-ASCII or UTF-8 (the reader takes UTF-8),
    else the text in that character set (:data:`ENCODINGS`). Raises BoundError for a character
    set outside :data:`ENCODINGS` or octets that are not text in it."""
    name = (encoding or "").strip().lower()
    codec = ENCODINGS.get(name) if name else "utf-8"
    if codec is None:
        shown = (encoding or "").strip()[:40]
        raise BoundError(f"payload-encoding {shown!r} is not read here (only {', '.join(_SHOWN)})")
    if codec in ("ascii", "utf-8"):
        return payload
    try:
        return payload.decode(codec)
    except UnicodeDecodeError as exc:
        raise BoundError(f"the payload is not {name} text: {exc.reason} at octet {exc.start}") from None


_SHOWN = ("US-ASCII", "UTF-8", "ISO-8859-1", "ISO-8859-15", "windows-1252", "UTF-16")
