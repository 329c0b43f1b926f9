"""FIPA SC00070 string representation: exact round trips, the string forms (literal and
byte-length encoded), agent identifiers in full, dates (UTC, local, relative), rejection of
bad text as StringFormError naming what was expected and where, and the human forms.

Interoperability with other platforms' forms is in test_fipa_string_form_interop.py."""

from __future__ import annotations

import math
import re
from datetime import timedelta, timezone

import msgspec
import pytest
from fipa_strategies import SAMPLE_TERMS, communicates, full_communicate
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_wm import ObjectQuery
from shared.fipa_codec.names import is_word
from shared.fipa_codec.string_form import (
    MAX_AID_DEPTH,
    AidExtras,
    StringFormError,
    content_as_json,
    format_datetime,
    parse,
    parse_datetime,
    summary,
    to_bytes,
    to_string,
)

INFORM = Performative.INFORM


def _msg(**kw: object) -> Communicate:
    return Communicate(performative=INFORM, **kw)  # type: ignore[arg-type]


# -- round trips ---------------------------------------------------------------------------


@pytest.mark.parametrize("performative", list(Performative))
@pytest.mark.parametrize("pretty", [False, True])
def test_every_act_with_every_parameter_round_trips(performative: Performative, pretty: bool) -> None:
    msg = full_communicate(performative)
    text = to_string(msg, pretty=pretty)
    assert text.startswith(f"({performative.value}")
    assert parse(text) == msg
    assert parse(to_bytes(msg, pretty=pretty)) == msg


@given(communicates())
@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
def test_string_round_trip(msg: Communicate) -> None:
    assert parse(to_string(msg)) == msg


@given(communicates())
@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
def test_bytes_round_trip(msg: Communicate) -> None:
    wire = to_bytes(msg, pretty=True)
    assert parse(wire) == msg
    assert parse(bytearray(wire)) == msg


@given(communicates(), st.none() | st.text(max_size=12), st.data())
@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
def test_every_buildable_communicate_round_trips_or_is_refused_by_its_rule(
    msg: Communicate, protocol: str | None, data: st.DataObject
) -> None:
    """Every communicate that can be built survives to_string -> parse unchanged; with any
    protocol text, one whose protocol is no SC00070 word cannot be built (ValueError naming
    the field), so it is never written as something else."""
    if protocol is not None and not is_word(protocol):
        with pytest.raises(ValueError, match=":protocol"):
            msgspec.structs.replace(msg, protocol=protocol)
        return
    msg = msgspec.structs.replace(msg, protocol=protocol)
    assert parse(to_string(msg)) == msg
    assert parse(to_bytes(msg, pretty=data.draw(st.booleans()))) == msg


@given(communicates())
@settings(max_examples=100, suppress_health_check=[HealthCheck.too_slow])
def test_string_survives_utf8_storage(msg: Communicate) -> None:
    # e.g. written to a UTF-8 log file and read back
    assert parse(to_string(msg).encode("utf-8").decode("utf-8")) == msg


def test_example_form() -> None:
    msg = Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("a_co", ("tcp/127.0.0.1:7447",)),
        receiver=(AgentIdentifier("a_ta"), AgentIdentifier("ag_ex")),
        content=b'say "hi" \\ now',
        language="L_HC",
        conversation_id="c1",
        reply_by=1795275000.0,
        user_params={"X-priority": "high"},
    )
    assert to_string(msg) == (
        "(request :sender (agent-identifier :name a_co :addresses (sequence tcp/127.0.0.1:7447))"
        " :receiver (set (agent-identifier :name a_ta) (agent-identifier :name ag_ex))"
        ' :content "say \\"hi\\" \\ now" :language L_HC :conversation-id c1'
        " :reply-by 20261121T153000000Z :X-priority high)"
    )


# -- content bytes -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "form"),
    [
        (b"hello world", '"hello world"'),
        ("żółw → ∑".encode(), '"żółw → ∑"'),
        (b'a"b\\c', '"a\\"b\\c"'),  # \" is the only escape; a backslash is itself
        (b"a\\\\b", '"a\\\\b"'),  # two backslashes stay two
        (b'\\"', '"\\\\""'),  # a backslash, then an escaped quote
        (b"ends\\", '#5"ends\\'),  # a literal cannot end in a backslash: byte-length encoded
        (b"line\nbreak", '"line\nbreak"'),  # text with a line break: still a literal
        ("tab\tżółw\r\n".encode(), '"tab\tżółw\r\n"'),  # JADE counts #n" in characters: no #n" for text
        (b"\x00\x1b", '"\x00\x1b"'),  # any UTF-8 is text, control characters too
        (b"\x00\xff", '#2"\x00\xff'),  # not UTF-8: byte-length encoded
        (b"\xc3\x28", '#2"\xc3('),  # invalid UTF-8
        ("\u0085".encode(), '"\x85"'),  # C1 control, valid UTF-8
        (b")", '")"'),
    ],
)
def test_content_forms(content: bytes, form: str) -> None:
    msg = _msg(content=content)
    text = to_string(msg)
    assert text == f"(inform :content {form})"
    assert parse(text).content == content
    assert parse(to_bytes(msg)).content == content


def test_byte_length_encoded_octets_are_raw_in_bytes_form() -> None:
    assert to_bytes(_msg(content=b"\x00\xff)")) == b'(inform :content #3"\x00\xff))'


@given(st.binary(max_size=100))
def test_any_content_round_trips(content: bytes) -> None:
    msg = _msg(content=content)
    assert parse(to_string(msg)).content == content
    assert parse(to_bytes(msg)).content == content


@pytest.mark.parametrize("term", SAMPLE_TERMS, ids=lambda t: type(t).__name__)
def test_language_content_round_trips(term: object) -> None:
    language, data = encode_content(term)  # type: ignore[arg-type]
    msg = _msg(content=data, language=language, encoding="msgpack")
    assert parse(to_string(msg)) == msg


def test_foreign_forms_are_read() -> None:
    text = (
        "(INFORM\n\t:Sender (AGENT-IDENTIFIER :name a_co)\r\n"
        ":receiver (set (agent-identifier :addresses (sequence tcp/x:1) :name b))"
        ' :content #5"hello :language fipa-sl :protocol fipa-request'
        ' :reply-with 42 :in-reply-to (a (b "c)") d) :ontology #2"ok'
        ' :conversation-id "back\\slash" :x-Lower-Case ok)'
    )
    msg = parse(text)
    assert msg.performative is INFORM
    assert msg.sender == AgentIdentifier("a_co")
    assert msg.receiver == (AgentIdentifier("b", ("tcp/x:1",)),)
    assert msg.content == b"hello"
    assert msg.language == "fipa-sl"
    assert msg.protocol == "fipa-request"
    assert msg.reply_with == "42"
    assert msg.in_reply_to == '(a (b "c)") d)'
    assert msg.ontology == "ok"
    assert msg.conversation_id == "back\\slash"  # a lone backslash stands for itself
    assert msg.user_params == {"x-Lower-Case": "ok"}


def test_empty_sets_and_strings() -> None:
    msg = parse('(inform :receiver (set) :reply-to (set) :content "" :X-e "")')
    assert msg == _msg(user_params={"X-e": ""})


# -- times ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("t", "token"),
    [
        (0.0, "19700101T000000000Z"),
        (1795275000.0, "20261121T153000000Z"),
        (1795275000.123, "20261121T153000123Z"),
        (-0.001, "19691231T235959999Z"),
        (-62135596800.0, "00010101T000000000Z"),
        (253402300799.999, "99991231T235959999Z"),
    ],
)
def test_datetime(t: float, token: str) -> None:
    assert format_datetime(t) == token
    assert parse_datetime(token) == t


def test_reply_by_is_rounded_to_the_millisecond() -> None:
    msg = _msg(reply_by=1795275000.0006)
    assert parse(to_string(msg)).reply_by == 1795275000.001


@pytest.mark.parametrize("t", [math.inf, -math.inf, math.nan, 1e300, -1e14])
def test_unwritable_times(t: float) -> None:
    with pytest.raises(ValueError):
        format_datetime(t)
    with pytest.raises(ValueError):
        to_string(_msg(reply_by=t))


PLUS_1 = timezone(timedelta(hours=1))
MINUS_0530 = timezone(-timedelta(hours=5, minutes=30))


@pytest.mark.parametrize(
    ("token", "tz", "t"),
    [
        ("20261121T153000000z", None, 1795275000.0),  # lower-case designator
        ("20261121t153000000Z", None, 1795275000.0),  # lower-case T
        ("20261121T163000000", PLUS_1, 1795275000.0),  # local time in tz
        ("20261121T100000250", MINUS_0530, 1795275000.25),
        ("20261121T153000000Z", PLUS_1, 1795275000.0),  # Z wins over tz
        ("00010101T000000000Z", PLUS_1, -62135596800.0),
    ],
)
def test_absolute_datetime_forms(token: str, tz: timezone | None, t: float) -> None:
    assert parse_datetime(token, tz=tz) == t
    assert parse(f"(inform :reply-by {token})", tz=tz).reply_by == t


def test_local_time_defaults_to_this_machines_zone() -> None:
    from datetime import datetime

    expected = datetime(2026, 11, 21, 15, 30).astimezone().timestamp()
    assert parse_datetime("20261121T153000000") == expected


NOW = 1795275000.0


@pytest.mark.parametrize(
    ("token", "t"),
    [
        ("+00000000T011500035", NOW + 4500.035),  # SC00070's example: 1 h 15 min 35 ms from now
        ("-00000000T000000500", NOW - 0.5),
        ("+00000001T000000000", NOW + 86400),
        ("+00000100T000000000z", NOW + 30 * 86400),  # a month is 30 days
        ("+00010000T000000000", NOW + 365 * 86400),  # a year is 365 days
        ("+00000000T990000000", NOW + 99 * 3600),  # fields of a duration may overflow
    ],
)
def test_relative_datetime(token: str, t: float) -> None:
    assert parse_datetime(token, now=NOW) == pytest.approx(t, abs=1e-6)
    assert parse(f"(inform :reply-by {token})", now=NOW).reply_by == pytest.approx(t, abs=1e-6)


def test_relative_datetime_defaults_to_now() -> None:
    import time

    before = time.time()
    t = parse_datetime("+00000000T000100000")
    assert before + 59 <= t <= time.time() + 61


@pytest.mark.parametrize(
    ("token", "reason"),
    [
        ("20261121T153000000B", "time zone designator 'B'"),
        ("20261321T153000000Z", "invalid date-time"),
        ("20261121T253000000Z", "invalid date-time"),
        ("00010101T000000000", "invalid date-time"),  # local time before the year 1 in tz
        ("2026-11-21T15:30:00Z", "expected a date-time"),
        ("20261121T1530", "expected a date-time"),
        ("tomorrow", "expected a date-time"),
    ],
)
def test_bad_datetime(token: str, reason: str) -> None:
    with pytest.raises(StringFormError, match=re.escape(reason)):
        parse(f"(inform :reply-by {token})", tz=PLUS_1)


# -- rejection -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "reason", "position"),
    [
        ("", "unexpected end", 0),
        ("inform", "expected '('", 0),
        ("(shout)", "unknown performative", 1),
        ("(inform", "unexpected end", 7),
        ("(inform) (inform)", "text after the end", 9),
        ("(inform :colour red)", "unknown message parameter", 8),
        ("(inform :language a :language b)", "repeated", 20),
        ("(inform :language)", "expected a value", 17),
        ("(inform :language :ontology x)", "found parameter", 18),
        ("(inform language x)", "expected ')' or a message parameter", 8),
        ('(inform :content "abc)', "unterminated string", 17),
        ('(inform :content #5"abc)', "announces 5 octets", 17),
        ('(inform :content #"abc")', "byte-length-encoded", 17),
        ('(inform :content #2"\u0100x)', "U+0000-U+00FF", 20),
        ("(inform :content (a b))", "expected a string after :content, found '('", 17),
        ("(inform :content :language x)", "expected a string after :content", 17),
        ("(inform :sender a_co)", "expected '(agent-identifier'", 16),
        ("(inform :sender (agent a_co))", "expected 'agent-identifier'", 17),
        ("(inform :sender (agent-identifier))", "without :name", 16),
        ("(inform :sender (agent-identifier :name 9x))", "expected an agent name (a SC00070 word)", 40),
        ("(inform :sender (agent-identifier :name a :name b))", "repeated", 42),
        ("(inform :sender (agent-identifier :NAME a :Name b))", "repeated", 42),
        ("(inform :sender (agent-identifier :name a :colour red))", "expected :name, :addresses", 42),
        ("(inform :sender (agent-identifier :name a :addresses x))", "expected '(sequence'", 53),
        ("(inform :sender (agent-identifier :name a :addresses (set x)))", "expected 'sequence'", 54),
        (
            "(inform :sender (agent-identifier :name a :resolvers (sequence (agent-identifier :name 9r))))",
            "expected an agent name (a SC00070 word), found '9r'",
            87,
        ),
        (
            "(inform :sender (agent-identifier :name a :resolvers (sequence) :resolvers (sequence)))",
            "repeated",
            64,
        ),
        ("(inform :sender (agent-identifier :name a :X-k v :x-k w :X-k u))", "repeated", 56),
        ("(inform :sender (agent-identifier :name a :resolvers (sequence a)))", "'(agent-identifier'", 63),
        ("(inform :X- v)", "expected a name after ':X-'", 8),
        ("(inform :sender (agent-identifier :name a :x- v))", "expected a name after ':x-'", 42),
        ("(inform :receiver (agent-identifier :name a))", "expected 'set'", 19),
        ("(inform :receiver (set (agent-identifier :name a)", "unterminated", 19),
        ("(inform :receiver (set a))", "expected '(agent-identifier'", 23),
        ('(inform :reply-by "20261121T153000000Z")', "expected a date-time", 18),
        ("(inform :in-reply-to (a (b)", "closing the expression", 27),
        ('(inform :ontology #1"\xff)', "invalid UTF-8", 18),
        ("(inform :ontology \ud800)", "lone surrogate", 18),
        (")", "expected '('", 0),
        # SC00070 words where the grammar asks for one: never a silent reading
        (
            "(inform :sender (agent-identifier :name a :addresses (sequence http://a (b) c)))",
            "expected an address (a SC00070 word), found '('",
            72,
        ),
        (
            '(inform :sender (agent-identifier :name a :addresses (sequence "tcp/x y")))',
            "expected an address (a SC00070 word), found a string",
            63,
        ),
        ('(inform :sender (agent-identifier :name "a_co"))', "expected an agent name (a SC00070 word)", 40),
        ("(inform :sender (agent-identifier :name (a b)))", "expected an agent name (a SC00070 word)", 40),
        ("(inform :sender (agent-identifier :name 12))", "found number '12'", 40),
        ('(inform :protocol "fipa request")', "expected a value for :protocol (a SC00070 word)", 18),
        ("(inform :protocol (fipa request))", "expected a value for :protocol (a SC00070 word)", 18),
        ("(inform :protocol 42)", "found number '42'", 18),
        # atoms that are no Word, Number or DateTime (SC00070 §2.3)
        ("(inform :language 9x)", "'9x', which is no SC00070 word, number or date-time", 18),
        ("(inform :X-a @b)", "'@b', which is no SC00070 word", 13),
        ("(inform :in-reply-to (a -b))", "'-b', which is no SC00070 word", 24),
        ("(inform :reply-by 2026-11-21)", "expected a date-time", 18),
        ("(inform :content 123)", "expected a string after :content, found number '123'", 17),
        ("(inform :content 20261121T153000000Z)", "found date-time", 17),
    ],
)
def test_bad_text_is_string_form_error(text: str, reason: str, position: int) -> None:
    with pytest.raises(StringFormError, match=re.escape(reason)) as info:
        parse(text)
    assert info.value.position == position
    assert isinstance(info.value, ValueError)


def test_bytes_input_positions_are_byte_offsets() -> None:
    with pytest.raises(StringFormError) as info:
        parse('(inform :ontology "ż" :x)'.encode())
    assert info.value.position == 23
    with pytest.raises(StringFormError, match="invalid UTF-8") as info:
        parse(b"(inform :ontology ab\xffc)")
    assert info.value.position == 20


def test_oversized_input() -> None:
    with pytest.raises(StringFormError, match="exceeds"):
        parse("(inform)", max_size=4)


def _parses_or_string_form_error(data: str | bytes) -> None:
    try:
        result = parse(data)
    except StringFormError as exc:
        assert exc.reason
        assert 0 <= exc.position <= len(data)
    else:
        assert isinstance(result, Communicate)


@given(st.text(max_size=80) | st.binary(max_size=80))
@settings(max_examples=1000)
def test_random_input_gives_string_form_error_only(data: str | bytes) -> None:
    _parses_or_string_form_error(data)


_ALPHABET = st.sampled_from(
    [
        "(",
        ")",
        '"',
        "\\",
        "#",
        "3",
        ":",
        " ",
        "x",
        "-",
        ":sender",
        "(set",
        "(sequence",
        "(agent-identifier",
        ":name",
        "a_co",
        "inform",
        ":content",
        ":reply-by",
        "20261121T153000000Z",
        ":X-a",
        '#2"',
        "\xff",
        "ż",
    ]
)


@given(st.lists(_ALPHABET, max_size=30).map("".join))
@settings(max_examples=1000)
def test_token_soup_gives_string_form_error_only(text: str) -> None:
    _parses_or_string_form_error(text)
    _parses_or_string_form_error(text.encode("utf-8"))


@given(communicates(), st.data())
@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
def test_truncated_and_mutated_text_gives_string_form_error_only(
    msg: Communicate, data: st.DataObject
) -> None:
    for form in (to_string(msg), to_bytes(msg)):
        cut = data.draw(st.integers(0, len(form) - 1))
        with pytest.raises(StringFormError):
            parse(form[:cut])
        pos = data.draw(st.integers(0, len(form) - 1))
        if isinstance(form, str):
            mutated: str | bytes = form[:pos] + data.draw(st.characters()) + form[pos + 1 :]
        else:
            mutated = form[:pos] + bytes([data.draw(st.integers(0, 255))]) + form[pos + 1 :]
        _parses_or_string_form_error(mutated)


def test_deep_nesting_does_not_overflow() -> None:
    with pytest.raises(StringFormError):
        parse("(inform :in-reply-to " + "(" * 100_000)
    deep = "(" * 50_000 + ")" * 50_000
    assert parse(f"(inform :in-reply-to {deep})").in_reply_to == deep


# -- human forms ---------------------------------------------------------------------------


def _query() -> Communicate:
    language, data = encode_content(ObjectQuery("jar"))
    return Communicate(
        performative=Performative.QUERY_REF,
        sender=AgentIdentifier("a_pl"),
        receiver=(AgentIdentifier("a_km"),),
        content=data,
        language=language,
        encoding="msgpack",
        protocol="fipa-query",
        conversation_id="ab12cd34ef56",
    )


def test_content_as_json() -> None:
    assert content_as_json(_query()) == '{"type":"object","name":"jar"}'
    assert content_as_json(_msg()) is None  # no content
    assert content_as_json(_msg(content=b"\x00", language="L_WM")) is None  # bad content
    assert content_as_json(_msg(content=b"\x80", language="fipa-sl")) is None  # unknown language
    q = _query()
    other = Communicate(performative=q.performative, content=q.content, language=q.language, encoding="json")
    assert content_as_json(other) is None  # not msgpack
    no_encoding = Communicate(performative=q.performative, content=q.content, language=q.language)
    assert content_as_json(no_encoding) == '{"type":"object","name":"jar"}'


@pytest.mark.parametrize("term", SAMPLE_TERMS, ids=lambda t: type(t).__name__)
def test_content_as_json_for_every_sample(term: object) -> None:
    language, data = encode_content(term)  # type: ignore[arg-type]
    rendered = content_as_json(_msg(content=data, language=language))
    assert rendered is not None and rendered.startswith("{") and "\n" not in rendered


def test_summary() -> None:
    assert summary(_query()) == (
        'a_pl → a_km  query-ref  [fipa-query c=ab12…]  L_WM  {"type":"object","name":"jar"}'
    )
    assert summary(_msg()) == "? → ?  inform"
    assert summary(_msg(content=b"\x00\x01\x02", language="L_WM")) == ("? → ?  inform  L_WM  <3 bytes>")
    assert summary(_msg(conversation_id="abc")) == "? → ?  inform  [c=abc]"
    assert summary(_msg(content=b"x"), content_text="line\nbreak\x1b[31m") == (
        "? → ?  inform  line\\nbreak\\x1b[31m"
    )
    long = summary(_msg(), content_text="y" * 500, max_content=10)
    assert long.endswith("yyyyyyyyy…")
    assert "\n" not in summary(full_communicate())


def test_human_string_form() -> None:
    text = to_string(_query(), human=True)
    assert ':content "{\\"type\\":\\"object\\",\\"name\\":\\"jar\\"}"' in text
    assert parse(text).content == b'{"type":"object","name":"jar"}'  # display only
    binary = to_string(_msg(content=b"\x00\x01"), human=True)
    assert binary == '(inform :content "<2 bytes, base64 AAE=>")'
    assert to_string(_msg(content=b"plain"), human=True) == '(inform :content "plain")'


def test_user_parameter_names_keep_their_case() -> None:
    msg = _msg(user_params={"X-a": "1", "x-a": "2", "X-A": "3"})
    assert parse(to_string(msg)) == msg
    with pytest.raises(StringFormError, match="repeated"):
        parse("(inform :X-a 1 :X-a 2)")
    with pytest.raises(StringFormError, match="repeated"):
        parse("(inform :language a :LANGUAGE b)")


# -- text values, agent identifiers, error locations --------------------------------------------


@pytest.mark.parametrize("value", ["a\nb", "tab\there", "żółw\r\n", "x\x00y", 'say "hi"\n'])
def test_text_with_control_characters_is_a_literal(value: str) -> None:
    """Text is a StringLiteral whenever that is valid SC00070: line breaks, tabs included."""
    msg = _msg(content=value.encode(), conversation_id=value, user_params={"X-v": value})
    text = to_string(msg)
    literal = '"' + value.replace('"', '\\"') + '"'
    assert text.count(literal) == 3 and "#" not in text
    assert parse(text) == msg
    assert parse(to_bytes(msg)) == msg


@pytest.mark.parametrize("protocol", ["fipa request", "", "(x)", "9x", "-p", "1.5", "a\tb", '"q"'])
def test_a_protocol_that_is_no_word_is_refused_when_built_or_decoded(protocol: str) -> None:
    with pytest.raises(ValueError, match=r"invalid :protocol .*not a FIPA SC00070 word"):
        _msg(protocol=protocol)
    wire = msgspec.msgpack.encode({"performative": "inform", "protocol": protocol})
    with pytest.raises(msgspec.ValidationError, match=":protocol"):
        msgspec.msgpack.decode(wire, type=Communicate)


def test_jade_literal_ending_in_a_backslash_is_read_as_jade_means_it() -> None:
    """JADE prints content ``C:\\dir\\`` as ``"C:\\dir\\"`` (StringACLCodec escapes only quotes)."""
    assert parse('(inform :content "C:\\dir\\" :language x)') == _msg(content=b"C:\\dir\\", language="x")
    assert parse('(inform :content "a \\"b\\" c\\")').content == b'a "b" c\\'  # the last \" closes
    # a later plain quote: \" is an escape (as in JADE's lexer), the literal runs on to it,
    # and what is left is no message (JADE fails on it too)
    with pytest.raises(StringFormError, match=re.escape("expected ')' or a message parameter")) as info:
        parse('(inform :content "a\\" :language "x")')
    assert info.value.position == 33
    with pytest.raises(StringFormError, match="unterminated string literal"):
        parse('(inform :content "no quote at all)')


@pytest.mark.parametrize("value", ["C:\\dir\\", "\\", 'a "quoted" \\', "żółw\\"])
def test_text_values_ending_in_a_backslash_are_byte_length_encoded(value: str) -> None:
    word = is_word(value)  # an address and :protocol are Words, written as they are
    msg = _msg(
        sender=AgentIdentifier("a", (value,) if word else ()),
        language=value,
        protocol=value if word else None,
        conversation_id=value,
        in_reply_to=value,
        user_params={"X-v": value},
    )
    text = to_string(msg)
    n = len(value.encode())
    assert f':language #{n}"' in text and f':X-v #{n}"' in text
    assert parse(text) == msg
    assert parse(to_bytes(msg)) == msg


def test_agent_identifier_is_read_in_full() -> None:
    text = (
        '(inform :sender (Agent-Identifier :X-b "2 3" :ADDRESSES (Sequence tcp/a:1 udp/b:2) :Name a_co'
        " :RESOLVERS (SEQUENCE (agent-identifier :name df :x-a (1 2)) (agent-identifier :name ams)) :X-a 1)"
        " :receiver (set (agent-identifier :name b :addresses (sequence) :resolvers (sequence))))"
    )
    msg = parse(text)
    assert msg.sender == AgentIdentifier(
        "a_co",
        ("tcp/a:1", "udp/b:2"),
        (AgentIdentifier("df", user=(("x-a", "(1 2)"),)), AgentIdentifier("ams")),
        (("X-b", "2 3"), ("X-a", "1")),  # in the order read
    )
    assert msg.receiver == (AgentIdentifier("b"),)  # empty :resolvers and :addresses carry nothing
    assert parse(to_string(msg)) == msg


def test_agent_identifier_string_form() -> None:
    """SC00070 §2.2: :name, :addresses, :resolvers (recursive), then the user parameters."""
    agent = AgentIdentifier(
        "a_co",
        ("tcp/127.0.0.1:7447",),
        (AgentIdentifier("df", ("tcp/h:1",), (AgentIdentifier("ams"),)), AgentIdentifier("df2")),
        (("X-role", "coordinator"), ("x-note", 'say "hi" (twice)'), ("X-n", "0.5")),
    )
    text = to_string(_msg(sender=agent))
    assert text == (
        "(inform :sender (agent-identifier :name a_co :addresses (sequence tcp/127.0.0.1:7447)"
        " :resolvers (sequence (agent-identifier :name df :addresses (sequence tcp/h:1)"
        " :resolvers (sequence (agent-identifier :name ams))) (agent-identifier :name df2))"
        ' :X-role coordinator :x-note "say \\"hi\\" (twice)" :X-n "0.5"))'
    )
    assert parse(text).sender == agent
    assert to_string(_msg(sender=AgentIdentifier("a", user=(("X-a", "v"),)))) == (
        "(inform :sender (agent-identifier :name a :X-a v))"
    )


def test_resolvers_and_agent_user_parameters_are_kept_rejected_or_dropped() -> None:
    text = (
        "(inform :sender (agent-identifier :name a :X-k v :resolvers (sequence"
        " (agent-identifier :name r :addresses (sequence tcp/r:1) :resolvers (sequence"
        " (agent-identifier :name rr :x-deep (1 2)))))) :reply-to (set (agent-identifier :name b :X-c d)))"
    )
    msg = parse(text)
    assert msg == parse(text, aid_extras="keep")
    assert msg.sender == AgentIdentifier(
        "a",
        resolvers=(
            AgentIdentifier("r", ("tcp/r:1",), (AgentIdentifier("rr", user=(("x-deep", "(1 2)"),)),)),
        ),
        user=(("X-k", "v"),),
    )
    assert msg.reply_to == (AgentIdentifier("b", user=(("X-c", "d"),)),)
    with pytest.raises(StringFormError, match="aid_extras='reject'") as info:
        parse(text, aid_extras="reject")
    assert info.value.position == text.index(":X-k")
    dropped = parse(text, aid_extras="drop")
    assert dropped.sender == AgentIdentifier("a")
    assert dropped.reply_to == (AgentIdentifier("b"),)
    # with "drop" the resolvers are not made agent identifiers, but must still be SC00070
    foreign = "(inform :sender (agent-identifier :name a :resolvers (sequence (agent-identifier :name 9))))"
    with pytest.raises(StringFormError, match="expected an agent name"):
        parse(foreign, aid_extras="drop")
    with pytest.raises(ValueError, match="aid_extras must be"):
        parse(text, aid_extras="ignore")  # type: ignore[arg-type]


def test_resolver_nesting_is_bounded() -> None:
    def nested(depth: int) -> str:
        aid = "(agent-identifier :name r)"
        for _ in range(depth - 1):
            aid = f"(agent-identifier :name r :resolvers (sequence {aid}))"
        return f"(inform :sender {aid})"

    agent = parse(nested(MAX_AID_DEPTH)).sender
    depth = 0
    while agent is not None:
        depth += 1
        agent = agent.resolvers[0] if agent.resolvers else None
    assert depth == MAX_AID_DEPTH
    assert parse(to_string(parse(nested(MAX_AID_DEPTH)))) == parse(nested(MAX_AID_DEPTH))
    modes: tuple[AidExtras, ...] = ("keep", "drop")
    for extras in modes:
        with pytest.raises(StringFormError, match="nested deeper"):
            parse(nested(MAX_AID_DEPTH + 1), aid_extras=extras)
    deep = "(inform :sender " + "(agent-identifier :name r :resolvers (sequence " * 10_000
    with pytest.raises(StringFormError, match="nested deeper"):
        parse(deep)


def test_errors_name_line_column_and_what_was_expected() -> None:
    text = "(inform\n :sender (agent-identifier :name a_co)\n :receiver (set a_km))"
    with pytest.raises(StringFormError) as info:
        parse(text)
    err = info.value
    assert err.reason == "expected '(agent-identifier', found 'a_km'"
    assert (err.position, err.line, err.column) == (text.index("a_km"), 3, 17)
    assert str(err) == "expected '(agent-identifier', found 'a_km' (at position 63, line 3 column 17)"
    with pytest.raises(StringFormError) as info:
        parse("(inform :reply-by 20261121T153000000Q)")
    assert "expected Z (UTC) or none" in info.value.reason
    with pytest.raises(StringFormError, match="expected one of the 22"):
        parse("(shout)")
    with pytest.raises(StringFormError, match=r"expected one of :sender .* or a user-defined :X-name"):
        parse("(inform :colour red)")
    with pytest.raises(StringFormError) as info:
        parse_datetime("never", 7)
    assert (info.value.position, info.value.line, info.value.column) == (7, None, None)


def test_bytes_input_line_and_column_count_bytes() -> None:
    with pytest.raises(StringFormError) as info:
        parse('(inform\n :ontology "ż" :x)'.encode())
    assert (info.value.line, info.value.column) == (2, 17)


@pytest.mark.parametrize("key", ["X-", "x-", "X-a b", "X-(", "X-a\tb"])
def test_unwritable_user_parameter_names(key: str) -> None:
    with pytest.raises(ValueError, match="user parameter name"):
        to_string(_msg(user_params={key: "1"}))
