"""FIPA SC00070 interoperability: what other platforms print is read field for field, and what
roco prints is grammatical beyond roco's own parser.

* fixtures/foreign_messages.txt: messages laid out as other platforms print them (JADE's
  ``ACLMessage.toString`` layout, upper-case keywords, agent identifiers with addresses,
  nested resolvers and ``X-`` parameters, byte-length-encoded strings, message ``X-`` parameters,
  local and relative times), each checked against the values written below;
* a second, independent writer (hypothesis) that varies everything SC00070 lets vary — case of
  keywords, white space, order of parameters, Word / StringLiteral / ByteLengthEncodedString,
  UTC / local / relative times — parse → print → parse holds for all of it;
* every one of the 22 performatives in JADE's layout;
* the reference reader of sc00070_reference.py, written from the grammar alone, reads roco's
  output to the same values.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import msgspec
import pytest
import sc00070_reference as ref
from fipa_strategies import (
    agent_names,
    aid_user_params,
    any_text,
    communicates,
    full_communicate,
    reply_times,
    user_keys,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.names import is_word
from shared.fipa_codec.string_form import (
    AidExtras,
    StringFormError,
    format_datetime,
    parse,
    to_bytes,
    to_string,
)

FIXTURES_FILE = Path(__file__).parent / "fixtures" / "foreign_messages.txt"
NOW = 1795275000.0  # 2026-11-21T15:30:00Z, "now" for relative times
PLUS_1 = timezone(timedelta(hours=1))  # the zone of local times


def _load_fixtures() -> dict[str, bytes]:
    data = FIXTURES_FILE.read_bytes()
    parts = re.split(rb"^==== (\S+)\n", data, flags=re.MULTILINE)
    return {parts[i].decode(): parts[i + 1] for i in range(1, len(parts), 2)}


FIXTURES = _load_fixtures()
JADE = "http://robolab:7778/acc"
JADE_ROBOLAB = "http://robolab:7778/acc"
JADE_DA0 = "da0@robolab:1099/JADE"
TEXT_FIELDS = ("language", "encoding", "ontology", "protocol", "conversation_id", "reply_with", "in_reply_to")

EXPECTED: dict[str, Communicate] = {
    "jade_inform": Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier("da0@jade-platform", (JADE,)),
        receiver=(AgentIdentifier("a_km", ("tcp/127.0.0.1:7447",)),),
        content=b'(weather (today raining) "Genoa")',
        reply_with="rw-7",
        in_reply_to="rw-6",
        language="fipa-sl",
        ontology="weather-ontology",
        reply_by=NOW + 3 * 3600,
        protocol="fipa-query",
        conversation_id="C1234_1700000000000",
        user_params={"X-priority": "2"},
    ),
    # JADE's byte content: base64 text flagged by :X-JADE-Encoding, kept as it is
    "jade_request_base64": Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("da1@jade-platform", (JADE,)),
        receiver=(AgentIdentifier("a_co"), AgentIdentifier("a_ta")),
        reply_to=(AgentIdentifier("da2@jade-platform"),),
        content=b"aGVsbG8gd29ybGQ=",
        encoding="base64",
        language="raw",
        protocol="fipa-request",
        conversation_id="conv 17",
        user_params={"X-JADE-Encoding": "Base64", "X-JADE-track": "a (tracked) value"},
    ),
    "upper_case": Communicate(
        performative=Performative.NOT_UNDERSTOOD,
        sender=AgentIdentifier("a_ta", ("tcp/10.0.0.2:7447", "udp/10.0.0.2:7448")),
        receiver=(AgentIdentifier("a_co"),),
        content=b"unknown action",
        language="L_HC",
        protocol="FIPA-REQUEST",  # values keep their case; only keywords are case-insensitive
        conversation_id="C-9",
        reply_by=NOW + 3 * 3600 + 0.5,
        user_params={"X-Note": "upper"},
    ),
    "byte_length_content": Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier("a_sd"),
        receiver=(AgentIdentifier("a_km"),),
        content='żółw ("x") and\na break:)'.encode(),  # 27 octets, 24 characters
        language="L_SD",
        encoding="utf-8",
        ontology="O_ó",
    ),
    # SC00023 §4 agent identifiers in full: resolvers (nested) and user-defined parameters
    "resolvers_and_aid_params": Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier(
            "da0@jade-platform",
            (JADE,),
            resolvers=(
                AgentIdentifier("df@jade-platform", (JADE,), (AgentIdentifier("ams@jade-platform"),)),
            ),
            user=(("X-JADE-agent-classname", "examples.PingAgent"), ("x-weight", "0.5")),
        ),
        receiver=(AgentIdentifier("a_km"),),
        content=b"ping",
    ),
    "fipa_spec_example": Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier("i"),
        receiver=(AgentIdentifier("j"),),
        content=b"weather (today, raining)",
        language="Prolog",
    ),
    "odd_whitespace": Communicate(
        performative=Performative.PROPOSE,
        sender=AgentIdentifier("a_pl"),
        receiver=(AgentIdentifier("a_co"), AgentIdentifier("a_hi")),
        content=b"plan\\tp1",  # no escape but \": a backslash and a t
        protocol="fipa-contract-net",
        conversation_id="c-7",
    ),
    "expressions": Communicate(
        performative=Performative.CFP,
        sender=AgentIdentifier("a_co"),
        content=b"call",
        in_reply_to='(query (weather "Genoa") 2026)',
        conversation_id="42",
        reply_with="-1.5e3",
        ontology="20261121T183000000Z",
        language="",
        user_params={"X-route": '(sequence (set a b) "c d")'},
    ),
    "reply_by_local": Communicate(
        performative=Performative.AGREE, sender=AgentIdentifier("a_ta"), reply_by=NOW + 3 * 3600
    ),
    "reply_by_relative": Communicate(
        performative=Performative.REQUEST, sender=AgentIdentifier("a_co"), reply_by=NOW + 4500.035
    ),
    "quotes_and_backslashes": Communicate(
        performative=Performative.FAILURE,
        sender=AgentIdentifier("a_ex"),
        content=b'C:\\robot\\log "x" done\\\\ (really)',
        conversation_id='say "hi"',
        reply_with="a\\b",
    ),
    "word_content": Communicate(  # SC00070 asks for a String; JADE also takes a Word
        performative=Performative.CONFIRM,
        sender=AgentIdentifier("a_km"),
        content=b"yes",
        language="fipa-sl0",
    ),
    "empty_sets_and_strings": Communicate(
        performative=Performative.CANCEL, language="", user_params={"X-e": ""}
    ),
    # in the layout of FIPA SC00037's examples
    "sc00037_request": Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("i"),
        receiver=(AgentIdentifier("j"),),
        content=b"((action (agent-identifier :name j) (deliver box017 (loc 12 19))))",
        protocol="fipa-request",
        language="fipa-sl",
        reply_with="order567",
    ),
    "sc00037_agree": Communicate(
        performative=Performative.AGREE,
        sender=AgentIdentifier("i"),
        receiver=(AgentIdentifier("j"),),
        content=b"((action (agent-identifier :name i) (deliver box017 (loc 12 19))) (priority order567 low))",
        in_reply_to="order567",
        protocol="fipa-request",
        language="fipa-sl",
    ),
    "sc00037_query_ref": Communicate(
        performative=Performative.QUERY_REF,
        sender=AgentIdentifier("i"),
        receiver=(AgentIdentifier("j"),),
        content=b"((all ?x (available-service j ?x)))",
        language="fipa-sl",
    ),
    # JADE's default agent names (local@host:port/JADE), JADE's layout
    "jade_default_names": Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier(JADE_DA0, (JADE_ROBOLAB,)),
        receiver=(AgentIdentifier("a_hi"),),
        reply_to=(AgentIdentifier(JADE_DA0, (JADE_ROBOLAB,)),),
        content=b"pour the jar into the bowl",
        reply_with="da0@robolab:1099/JADE1700000000001",
        language="L_HC",
        protocol="fipa-request",
        conversation_id="C1717_1700000000000",
    ),
    # text with a line break and a tab in a literal, non-ASCII (JADE counts #n" in characters)
    "jade_text_with_line_breaks": Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier("ams@robolab:1099/JADE"),
        receiver=(AgentIdentifier(JADE_DA0),),
        content='línea 1\n\tżółw "quoted"'.encode(),
        language="fipa-sl",
        ontology="FIPA Agent Management",
        conversation_id="C5_1",
    ),
    # JADE prints content ending in a backslash as "…\" (it escapes only quotes): read as JADE means it
    "jade_content_ending_in_backslash": Communicate(
        performative=Performative.FAILURE,
        sender=AgentIdentifier("da1@robolab:1099/JADE"),
        content=b"C:\\robot\\log\\",
        in_reply_to="rw-3",
        language="fipa-sl",
        protocol="fipa-request",
        conversation_id="C9_2",
    ),
}
# accepted by roco (and JADE), not by the grammar read strictly
NOT_STRICT_SC00070 = {"word_content", "jade_content_ending_in_backslash"}


def _parse(data: str | bytes, aid_extras: AidExtras = "keep") -> Communicate:
    return parse(data, now=NOW, tz=PLUS_1, aid_extras=aid_extras)


def _fields(msg: Communicate) -> dict[str, object]:
    return msgspec.structs.asdict(msg)


def test_every_fixture_has_expected_values() -> None:
    assert set(FIXTURES) == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_foreign_message_is_read_field_for_field(name: str) -> None:
    msg = _parse(FIXTURES[name])
    assert _fields(msg) == _fields(EXPECTED[name])
    # parse -> print -> parse
    assert parse(to_string(msg)) == msg
    assert parse(to_bytes(msg, pretty=True)) == msg
    # and roco's reprint is grammatical
    assert ref.read(to_bytes(msg), strict_words=False)["performative"] == msg.performative.value


@pytest.mark.parametrize("name", sorted(set(EXPECTED) - NOT_STRICT_SC00070))
def test_fixtures_are_grammatical(name: str) -> None:
    """The fixtures themselves pass the reference reader: they are SC00070, not roco dialect."""
    assert ref.read(FIXTURES[name])["performative"] == EXPECTED[name].performative.value


@pytest.mark.parametrize("name", sorted(NOT_STRICT_SC00070))
def test_leniencies_are_not_strict_sc00070(name: str) -> None:
    with pytest.raises(ref.Reject):
        ref.read(FIXTURES[name])


def test_jade_text_is_written_back_as_a_literal_jade_reads() -> None:
    """Text with line breaks, tabs and non-ASCII goes back as a quoted string, never as #n"
    (which JADE would count in characters); the names as the words they are."""
    msg = _parse(FIXTURES["jade_text_with_line_breaks"])
    text = to_string(msg)
    assert ':content "línea 1\n\tżółw \\"quoted\\""' in text and "#" not in text
    assert "(agent-identifier :name ams@robolab:1099/JADE)" in text
    assert ':ontology "FIPA Agent Management"' in text


def test_jade_content_ending_in_a_backslash() -> None:
    msg = _parse(FIXTURES["jade_content_ending_in_backslash"])
    assert msg.content == b"C:\\robot\\log\\"
    assert msg.language == "fipa-sl"  # what follows the literal is read as it stands
    # roco writes it back byte-length encoded: no literal can end in a backslash unambiguously
    assert ':content #13"C:\\robot\\log\\' in to_string(msg)


def test_resolvers_and_aid_params_are_read_field_for_field() -> None:
    data = FIXTURES["resolvers_and_aid_params"]
    sender = _parse(data).sender
    assert sender is not None
    assert (sender.name, sender.addresses) == ("da0@jade-platform", (JADE,))
    assert sender.user == (("X-JADE-agent-classname", "examples.PingAgent"), ("x-weight", "0.5"))
    (df,) = sender.resolvers
    assert (df.name, df.addresses, df.user) == ("df@jade-platform", (JADE,), ())
    (ams,) = df.resolvers
    assert (ams.name, ams.addresses, ams.resolvers, ams.user) == ("ams@jade-platform", (), (), ())
    # the reference reader finds the same in the fixture and in roco's reprint
    assert ref.read(data)["sender"] == _ref_aid(sender)
    reprint = to_bytes(_parse(data))
    assert ref.read(reprint, strict_words=False)["sender"] == _ref_aid(sender)
    assert b":resolvers (sequence (agent-identifier :name df@jade-platform" in reprint
    assert reprint.index(b":resolvers") < reprint.index(b":X-JADE-agent-classname examples.PingAgent")


def test_resolvers_and_aid_params_can_be_rejected_where_they_stand_or_dropped() -> None:
    data = FIXTURES["resolvers_and_aid_params"]
    with pytest.raises(StringFormError, match="aid_extras='reject'") as info:
        _parse(data, aid_extras="reject")
    assert info.value.position == data.index(b":resolvers")
    line_start = data.rindex(b"\n", 0, info.value.position) + 1
    assert (info.value.line, info.value.column) == (2, info.value.position - line_start + 1)
    dropped = _parse(data, aid_extras="drop")
    assert dropped.sender == AgentIdentifier("da0@jade-platform", (JADE,))
    assert dropped.receiver == EXPECTED["resolvers_and_aid_params"].receiver


# -- JADE's layout for every act ------------------------------------------------------------------


def _jade_value(value: str) -> str:
    return value if re.fullmatch(r"[A-Za-z_][\w.-]*", value) else '"' + value.replace('"', '\\"') + '"'


def _jade_aid(agent: AgentIdentifier) -> str:
    out = f"( agent-identifier :name {agent.name} "
    if agent.addresses:
        out += " :addresses (sequence " + "".join(f"{a} " for a in agent.addresses) + ")"
    if agent.resolvers:
        out += " :resolvers (sequence " + "".join(_jade_aid(r) + " " for r in agent.resolvers) + ")"
    out += "".join(f" :{k} {_jade_value(v)} " for k, v in agent.user)
    return out + ")"


def _jade_layout(msg: Communicate) -> str:
    """``msg`` laid out as JADE's ACLMessage.toString does (upper-case act, one line per
    parameter, doubled blanks, user parameters last); values here are words or plain text."""
    assert msg.sender is not None and msg.reply_by is not None
    out = f"({msg.performative.value.upper()}\n :sender  {_jade_aid(msg.sender)}\n"
    out += " :receiver  (set " + "".join(_jade_aid(r) + " " for r in msg.receiver) + ")\n"
    out += " :reply-to  (set \n" + "".join(_jade_aid(r) + " " for r in msg.reply_to) + ")\n"
    out += ' :content  "' + msg.content.decode().replace('"', '\\"') + '" \n'
    for name, value in [
        ("reply-with", msg.reply_with),
        ("in-reply-to", msg.in_reply_to),
        ("encoding", msg.encoding),
        ("language", msg.language),
        ("ontology", msg.ontology),
    ]:
        out += f" :{name}  {value} "
    out += f" :reply-by  {format_datetime(msg.reply_by)}\n :protocol  {msg.protocol}\n"
    out += f" :conversation-id  {msg.conversation_id} "
    out += "".join(f":{k} {v} " for k, v in msg.user_params.items())
    return out + ")"


@pytest.mark.parametrize("performative", list(Performative))
def test_every_act_in_jade_layout(performative: Performative) -> None:
    base = full_communicate(performative)
    msg = msgspec.structs.replace(
        base, content=b'(done (action a_ta "pour"))', user_params={"X-priority": "2", "X-note": "ok"}
    )
    text = _jade_layout(msg)
    assert parse(text) == msg
    assert msg.reply_to[0].resolvers and msg.reply_to[0].user  # agent identifiers in full
    keywords = r"\b(agent-identifier|sequence|set)\b|(?<=\s):(?!X-)[a-z][a-z-]*"
    shouted = re.sub(keywords, lambda m: m[0].upper(), text)
    assert ":SENDER" in shouted and "AGENT-IDENTIFIER" in shouted and ":X-priority" in shouted
    assert ":RESOLVERS" in shouted and ":X-role" in shouted
    assert parse(shouted) == msg
    assert parse(to_string(parse(text))) == msg  # parse -> print -> parse
    assert ref.read(text.encode())["performative"] == performative.value


# -- a second writer: everything SC00070 lets vary ------------------------------------------------

_SC_WORD = re.compile(r'[^\x00-\x20()#0-9\-@":][^\x00-\x20()]*\Z')  # a Word roco reads as a value
_SPACES = st.sampled_from([" ", "  ", "\t", "\n", "\r\n", "\n\t ", " \x0c ", "\x0b"])
_NO_SPACE = st.sampled_from(["", " ", "\n"])
_CASES = st.sampled_from([str.lower, str.upper, str.title])


@st.composite
def _string_form(draw: st.DrawFn, data: bytes, word_ok: bool = True) -> bytes:
    """``data`` as a Word, a StringLiteral or a ByteLengthEncodedString, whichever fits."""
    forms = [b'#%d"' % len(data) + data]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return forms[0]
    if not text.endswith("\\"):
        forms.append(b'"' + data.replace(b'"', b'\\"') + b'"')
    if word_ok and _SC_WORD.match(text) and is_word(text):  # "+0", ".5": Numbers, not Words
        forms.append(data)
    return draw(st.sampled_from(forms))


@st.composite
def _aid_form(draw: st.DrawFn, agent: AgentIdentifier) -> bytes:
    """``agent`` with its parameters in any order, user parameters keeping their own order."""
    case = draw(_CASES)
    # :name and addresses are Words (SC00070 §2.2), written as they are
    params = [case(":name").encode() + draw(_SPACES).encode() + agent.name.encode()]
    # an empty (sequence) where there is nothing, or not
    empty_addresses: bool = draw(st.booleans())
    empty_resolvers: bool = draw(st.booleans())
    if agent.addresses or empty_addresses:
        urls = b"".join(draw(_SPACES).encode() + a.encode() for a in agent.addresses)
        params.append(case(":addresses").encode() + b" (" + case("sequence").encode() + urls + b")")
    if agent.resolvers or empty_resolvers:
        items = b"".join(draw(_NO_SPACE).encode() + draw(_aid_form(r)) for r in agent.resolvers)
        params.append(case(":resolvers").encode() + b" (" + case("sequence").encode() + items + b")")
    user = [
        f":{key}".encode() + draw(_SPACES).encode() + draw(_string_form(value.encode()))
        for key, value in agent.user
    ]
    order = draw(st.permutations([False] * len(params) + [True] * len(user)))  # True: a user slot
    fixed, users = iter(draw(st.permutations(params))), iter(user)
    params = [next(users) if is_user else next(fixed) for is_user in order]
    body = b"".join(draw(_SPACES).encode() + p for p in params)
    head = b"(" + draw(_NO_SPACE).encode() + case("agent-identifier").encode()
    return head + body + draw(_NO_SPACE).encode() + b")"


@st.composite
def _set_form(draw: st.DrawFn, agents: tuple[AgentIdentifier, ...]) -> bytes:
    items = b"".join(draw(_NO_SPACE).encode() + draw(_aid_form(a)) for a in agents)
    return b"(" + draw(_CASES)("set").encode() + items + draw(_NO_SPACE).encode() + b")"


def _digits(dt: datetime) -> str:
    return f"{dt.year:04d}{dt.month:02d}{dt.day:02d}T{dt.hour:02d}{dt.minute:02d}{dt.second:02d}" + (
        f"{dt.microsecond // 1000:03d}"
    )


@st.composite
def _datetime_form(draw: st.DrawFn, t: float) -> bytes:
    """``t`` as a UTC, local (zone PLUS_1) or relative (to NOW) DateTime."""
    ms = round(t * 1000)
    utc = datetime(1970, 1, 1, tzinfo=UTC) + timedelta(milliseconds=ms)
    kind = draw(st.sampled_from(["utc", "local", "relative"]))
    if kind == "local" and ms < 253402297200000:  # before 9999-12-31T23:00Z: representable in PLUS_1
        return _digits(utc.astimezone(PLUS_1)).encode()
    if kind == "relative":
        delta = ms - round(NOW * 1000)
        fields, rest = [], abs(delta)
        for unit in (365 * 86_400_000, 30 * 86_400_000, 86_400_000, 3_600_000, 60_000, 1000, 1):
            fields.append(rest // unit)
            rest %= unit
        y, mo, d, h, mi, s, milli = fields
        sign = "+" if delta >= 0 else "-"
        return f"{sign}{y:04d}{mo:02d}{d:02d}T{h:02d}{mi:02d}{s:02d}{milli:03d}".encode()
    return (_digits(utc) + draw(st.sampled_from(["Z", "z"]))).encode()


@st.composite
def foreign_forms(draw: st.DrawFn, msg: Communicate) -> bytes:
    """``msg`` written as another platform might: any case, spacing, order and string form."""
    case = draw(_CASES)
    params: list[bytes] = []

    def add(name: str, value: bytes) -> None:
        params.append(case(":" + name).encode() + draw(_SPACES).encode() + value)

    if msg.sender is not None:
        add("sender", draw(_aid_form(msg.sender)))
    if msg.receiver or draw(st.booleans()):
        add("receiver", draw(_set_form(msg.receiver)))
    if msg.reply_to:
        add("reply-to", draw(_set_form(msg.reply_to)))
    if msg.content:
        add("content", draw(_string_form(msg.content)))
    for name in TEXT_FIELDS:
        value = getattr(msg, name)
        if value is not None:  # :protocol is a Word (SC00070 §2.2), the others Expressions
            form = value.encode() if name == "protocol" else draw(_string_form(value.encode()))
            add(name.replace("_", "-"), form)
    if msg.reply_by is not None:
        add("reply-by", draw(_datetime_form(msg.reply_by)))
    for key, value in msg.user_params.items():
        params.append(f":{key}".encode() + draw(_SPACES).encode() + draw(_string_form(value.encode())))
    params = draw(st.permutations(params))
    head = b"(" + draw(_NO_SPACE).encode() + draw(_CASES)(msg.performative.value).encode()
    return head + b"".join(draw(_SPACES).encode() + p for p in params) + draw(_NO_SPACE).encode() + b")"


@given(communicates(), st.data())
@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
def test_foreign_forms_parse_print_parse(msg: Communicate, data: st.DataObject) -> None:
    form = data.draw(foreign_forms(msg))
    parsed = _parse(form)
    assert parsed == msg  # field for field, whatever the form
    again = parse(to_string(parsed))
    assert again == parsed


# -- roco's output read by the reference reader ---------------------------------------------------


def _ref_aid(agent: AgentIdentifier) -> dict[str, object]:
    """What the reference reader must find for ``agent``, resolvers and user parameters included."""
    return {
        "name": agent.name,
        "addresses": list(agent.addresses),
        "resolvers": [_ref_aid(r) for r in agent.resolvers],
        "user": dict(agent.user),
    }


def _ref_view(msg: Communicate) -> dict[str, object]:
    """What the reference reader must find in roco's output for ``msg``."""
    view: dict[str, object] = {"performative": msg.performative.value, "user": dict(msg.user_params)}
    if msg.sender is not None:
        view["sender"] = _ref_aid(msg.sender)
    if msg.receiver:
        view["receiver"] = [_ref_aid(a) for a in msg.receiver]
    if msg.reply_to:
        view["reply-to"] = [_ref_aid(a) for a in msg.reply_to]
    if msg.content:
        view["content"] = msg.content
    for name in TEXT_FIELDS:
        if getattr(msg, name) is not None:
            view[name.replace("_", "-")] = getattr(msg, name)
    if msg.reply_by is not None:
        view["reply-by"] = format_datetime(msg.reply_by)
    return view


@given(communicates())
@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
def test_reference_reader_reads_rocos_output(msg: Communicate) -> None:
    # names, addresses and :protocol are Words, written as Words: the strict reader reads them
    assert ref.read(to_bytes(msg)) == _ref_view(msg)
    assert ref.read(to_bytes(msg, pretty=True)) == _ref_view(msg)


_urls = st.from_regex(r"(tcp|udp|http)/[a-z0-9.]{1,12}:[0-9]{1,5}", fullmatch=True)
_words = st.from_regex(r"[A-Za-z_][A-Za-z0-9_.+/:@\-]{0,15}", fullmatch=True)


def _url_agents(depth: int = 3) -> st.SearchStrategy[AgentIdentifier]:
    """Agent identifiers whose addresses are URLs, resolvers included (``depth`` deep)."""
    addresses = st.lists(_urls, max_size=2).map(tuple)
    if depth <= 1:
        return st.builds(AgentIdentifier, agent_names, addresses, st.just(()), aid_user_params)
    resolvers = st.lists(_url_agents(depth - 1), min_size=1, max_size=2).map(tuple)
    plain = st.builds(AgentIdentifier, agent_names, addresses)
    return plain | st.builds(AgentIdentifier, agent_names, addresses, resolvers, aid_user_params)


@st.composite
def _plain_communicates(draw: st.DrawFn) -> Communicate:
    """Communicates whose addresses are URLs and protocol a Word, as SC00070 asks."""
    agent = _url_agents()
    return Communicate(
        performative=draw(st.sampled_from(Performative)),
        sender=draw(st.none() | agent),
        receiver=tuple(draw(st.lists(agent, max_size=3))),
        reply_to=tuple(draw(st.lists(agent, max_size=2))),
        content=draw(st.binary(max_size=40) | st.text(max_size=40).map(str.encode)),
        language=draw(st.none() | any_text),
        encoding=draw(st.none() | any_text),
        ontology=draw(st.none() | any_text),
        protocol=draw(st.none() | _words),
        conversation_id=draw(st.none() | any_text),
        reply_with=draw(st.none() | any_text),
        in_reply_to=draw(st.none() | any_text),
        reply_by=draw(st.none() | reply_times),
        user_params=draw(st.dictionaries(user_keys, any_text, max_size=3)),
    )


@given(_plain_communicates())
@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
def test_reference_reader_strict(msg: Communicate) -> None:
    assert ref.read(to_bytes(msg)) == _ref_view(msg)


@pytest.mark.parametrize("performative", list(Performative))
def test_reference_reader_every_act_every_parameter(performative: Performative) -> None:
    msg = full_communicate(performative)
    assert ref.read(to_bytes(msg)) == _ref_view(msg)
    assert ref.read(to_bytes(msg, pretty=True)) == _ref_view(msg)


@pytest.mark.parametrize(
    "text",
    [
        b'(inform :content "a\\")',  # a literal cannot end in a backslash
        b"(inform :content abc)",  # :content is a String
        b"(inform :reply-by tomorrow)",
        b'(inform :protocol "fipa request")',
        b"(inform :sender (agent-identifier :addresses (sequence) :name a))",  # :name first
        b"(inform :language a :LANGUAGE b)",
        b"(inform :colour red)",
        b"(shout)",
        b'(inform :content #5"abc)',
        b"(inform :receiver (set a))",
        b"(inform) x",
    ],
)
def test_reference_reader_rejects(text: bytes) -> None:
    """The reference reader is not a pushover: it rejects what the grammar rejects."""
    with pytest.raises(ref.Reject):
        ref.read(text)


PARAMETERS = [f for f in Communicate.__struct_fields__ if f != "performative"]


def test_thirteen_parameters() -> None:
    """SC00061 §2: the performative and 12 more, plus the user-defined ones."""
    assert len(PARAMETERS) + 1 == 14 and PARAMETERS[-1] == "user_params"


@pytest.mark.parametrize("field", PARAMETERS)
@pytest.mark.parametrize("performative", [Performative.INFORM, Performative.REQUEST_WHENEVER])
def test_each_parameter_alone(field: str, performative: Performative) -> None:
    full = full_communicate(performative)
    msg = Communicate(performative=performative, **{field: getattr(full, field)})
    if field == "content":  # binary content wants its language and encoding only to be read
        msg = msgspec.structs.replace(msg, content=full.content)
    name = "X-priority" if field == "user_params" else field.replace("_", "-")
    text = to_string(msg)
    assert f" :{name} " in text
    assert parse(text) == msg  # print -> parse
    assert ref.read(to_bytes(msg)) == _ref_view(msg)
    wire = to_bytes(msg, pretty=True)
    head = b"(" + performative.value.encode()
    foreign = b"( " + performative.value.upper().encode() + wire[len(head) :].replace(b"\n :", b"\r\n\t:")
    assert foreign != wire
    assert parse(to_string(_parse(foreign))) == msg  # parse -> print -> parse
