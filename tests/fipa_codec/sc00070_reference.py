"""A minimal reader of FIPA SC00070 written from its grammar alone (§2.2 syntax, §2.3 lexical
rules), independent of ``shared.fipa_codec.string_form``: a tokenizer and a recursive descent,
used by the tests to show that what roco prints is grammatical beyond roco's own parser.

It reads octets (``to_bytes``) and is strict where roco's parser is lenient: ``:content`` must
be a String, ``:reply-by`` a DateTime, ``:name`` a Word, the agent-identifier parameters come in
the grammar's order (``:name``, ``:addresses``, ``:resolvers``, user parameters), user-defined
parameter names start with ``X-``, and each message parameter appears at most once (SC00070 notes).
With ``strict_words`` (the default) ``:protocol`` must be a Word and an address a Word (a URL);
without it a String is let through there too (roco writes only Words there; the option stays for
other writers' output).

The result is plain data: ``{"performative": str, "sender": aid, "receiver": [aid, …],
"content": bytes, "language": str, …, "reply-by": str, "user": {name: value}}`` where an
``aid`` is ``{"name", "addresses", "resolvers", "user"}`` and an Expression's value is its
text (Word, Number, DateTime), its string value, or a list for a parenthesised one.
"""

from __future__ import annotations

import re
from typing import Any

ACTS = frozenset(
    {
        *("accept-proposal", "agree", "cancel", "cfp", "confirm", "disconfirm", "failure", "inform"),
        *("inform-if", "inform-ref", "not-understood", "propagate", "propose", "proxy", "query-if"),
        *("query-ref", "refuse", "reject-proposal", "request", "request-when", "request-whenever"),
        "subscribe",
    }
)
assert len(ACTS) == 22  # FIPA SC00037
EXPRESSION_PARAMS = frozenset(
    {":reply-with", ":in-reply-to", ":language", ":encoding", ":ontology", ":conversation-id"}
)

_LITERAL = re.compile(rb'"((?:\\"|[^"])*+)"')  # §2.3 StringLiteral, \" the only escape
_BLE = re.compile(rb'#([0-9]+)"')  # §2.3 ByteLengthEncodedString head
_RUN = re.compile(rb"[^\x00-\x20()]+")
_DATETIME = re.compile(rb"[+-]?[0-9]{8}[Tt][0-9]{9}[A-Za-z]?\Z")
_NUMBER = re.compile(rb"[+-]?([0-9]+|[0-9]+\.[0-9]*|[0-9]*\.[0-9]+)([eE][+-]?[0-9]+)?\Z")
_WORD = re.compile(rb"[^\x00-\x20()#0-9\-@][^\x00-\x20()]*\Z")


class Reject(Exception):
    """Not SC00070."""


Token = tuple[str, Any]  # ("(", None) | (")", None) | ("string", bytes) | ("word"|"number"|"datetime", str)


def tokenize(data: bytes) -> list[Token]:
    out: list[Token] = []
    i = 0
    while i < len(data):
        c = data[i : i + 1]
        if c <= b" ":
            i += 1
        elif c in b"()":
            out.append((c.decode(), None))
            i += 1
        elif c == b'"':
            m = _LITERAL.match(data, i)
            if m is None:
                raise Reject(f"bad string literal at {i}")
            out.append(("string", m.group(1).replace(b'\\"', b'"')))
            i = m.end()
        elif c == b"#":
            m = _BLE.match(data, i)
            if m is None or m.end() + int(m.group(1)) > len(data):
                raise Reject(f"bad byte-length-encoded string at {i}")
            n = int(m.group(1))
            out.append(("string", data[m.end() : m.end() + n]))
            i = m.end() + n
        else:
            m = _RUN.match(data, i)
            assert m is not None
            run = m.group(0)
            kind = (
                "datetime"
                if _DATETIME.match(run)
                else "number"
                if _NUMBER.match(run)
                else "word"
                if _WORD.match(run)
                else None
            )
            if kind is None:
                raise Reject(f"{run!r} is no Word, Number or DateTime")
            out.append((kind, run.decode("utf-8")))
            i = m.end()
    return out


class Reader:
    def __init__(self, data: bytes, strict_words: bool) -> None:
        self.toks = tokenize(data)
        self.i = 0
        self.strict_words = strict_words

    def take(self, *kinds: str) -> Any:
        if self.i >= len(self.toks) or self.toks[self.i][0] not in kinds:
            raise Reject(f"expected {kinds} at token {self.i}")
        self.i += 1
        return self.toks[self.i - 1][1]

    def at(self, kind: str, word: str | None = None) -> bool:
        if self.i >= len(self.toks) or self.toks[self.i][0] != kind:
            return False
        return word is None or self.toks[self.i][1].lower() == word

    def keyword(self, word: str) -> None:
        if not self.at("word", word):
            raise Reject(f"expected {word} at token {self.i}")
        self.i += 1

    def text(self, value: Any) -> Any:
        return value.decode("utf-8") if isinstance(value, bytes) else value

    def expression(self) -> Any:
        if self.at("("):
            self.take("(")
            items = []
            while not self.at(")"):
                items.append(self.expression())
            self.take(")")
            return items
        return self.text(self.take("word", "string", "number", "datetime"))

    def word_or_string(self) -> str:
        return self.text(self.take("word") if self.strict_words else self.take("word", "string"))

    def sequence(self, head: str, item: Any) -> list[Any]:
        self.take("(")
        self.keyword(head)
        items = []
        while not self.at(")"):
            items.append(item())
        self.take(")")
        return items

    def agent_identifier(self) -> dict[str, Any]:
        self.take("(")
        self.keyword("agent-identifier")
        self.keyword(":name")
        aid: dict[str, Any] = {"name": self.take("word"), "addresses": [], "resolvers": [], "user": {}}
        if self.at("word", ":addresses"):
            self.i += 1
            aid["addresses"] = self.sequence("sequence", self.word_or_string)
        if self.at("word", ":resolvers"):
            self.i += 1
            aid["resolvers"] = self.sequence("sequence", self.agent_identifier)
        while self.at("word") and self.toks[self.i][1][:3].lower() == ":x-":
            name = self.take("word")
            aid["user"][name[1:]] = self.expression()
        self.take(")")
        return aid

    def message(self) -> dict[str, Any]:
        self.take("(")
        act = self.take("word").lower()
        if act not in ACTS:
            raise Reject(f"unknown act {act}")
        msg: dict[str, Any] = {"performative": act, "user": {}}
        while not self.at(")"):
            name = self.take("word")
            key = name.lower()
            if key in msg or name[1:] in msg["user"]:
                raise Reject(f"{name} twice")
            if key == ":sender":
                msg[key] = self.agent_identifier()
            elif key in (":receiver", ":reply-to"):
                msg[key] = self.sequence("set", self.agent_identifier)
            elif key == ":content":
                msg[key] = self.take("string")
            elif key == ":reply-by":
                msg[key] = self.take("datetime")
            elif key == ":protocol":
                msg[key] = self.word_or_string()
            elif key in EXPRESSION_PARAMS:
                msg[key] = self.expression()
            elif key.startswith(":x-") and len(name) > 3:
                msg["user"][name[1:]] = self.expression()
            else:
                raise Reject(f"unknown parameter {name}")
        self.take(")")
        if self.i != len(self.toks):
            raise Reject("text after the message")
        return {k.lstrip(":"): v for k, v in msg.items()}


def read(data: bytes, *, strict_words: bool = True) -> dict[str, Any]:
    """The message in ``data`` as plain data; raises Reject when it is not SC00070."""
    return Reader(data, strict_words).message()
