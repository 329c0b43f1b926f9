"""`roco sniff` (services/sniff/sniffer.py): live communicates from a Zenoh router on a loopback port,
filtered by agent, channel, performative and conversation, printed in the FIPA SC00070 string
form (readable content, or exact with --raw), malformed payloads reported without stopping."""

from __future__ import annotations

import queue
import re
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field

import msgspec
import pytest
import zenoh

from services.fleet.launcher import free_port
from services.runtime import keys
from services.runtime.session import open_client
from services.sniff.sniffer import Filters, parse_filters, render, sniff
from services.spec.model import default_spec
from shared.fipa_codec import Communicate, Performative, encode
from shared.fipa_codec.aid import aid
from shared.fipa_codec.batch import pack
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery
from shared.fipa_codec.string_form import parse
from tests.support.router import embedded_router

HEADER = re.compile(r"^\d\d:\d\d:\d\d\.\d{3}  (C\d)  (\w+) → (\w+)  \((\d+) B\)")
TIMEOUT = 10.0


def comm(
    performative: str,
    sender: str,
    receiver: str,
    content: msgspec.Struct | None = None,
    *,
    conversation: str = "c-1",
    reply_with: str | None = None,
) -> Communicate:
    language, body = encode_content(content) if content is not None else (None, b"")
    return Communicate(
        performative=Performative(performative),
        sender=aid(sender),
        receiver=(aid(receiver),),
        content=body,
        language=language,
        encoding="msgpack" if body else None,
        protocol="fipa-query",
        conversation_id=conversation,
        reply_with=reply_with,
    )


@pytest.fixture(scope="module")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """An embedded router on a free loopback port (tests/support/router.py)."""
    yield from embedded_router(tmp_path_factory, "sniff")


@pytest.fixture
def publisher(router: str) -> Iterator[zenoh.Session]:
    session = open_client(router)
    try:
        yield session
    finally:
        session.close()


@dataclass
class Sniffer:
    """``sniff`` running in a thread; its output lines arrive in ``lines``."""

    endpoint: str
    lines: queue.SimpleQueue[str] = field(default_factory=queue.SimpleQueue)
    stop: threading.Event = field(default_factory=threading.Event)
    ready: threading.Event = field(default_factory=threading.Event)
    result: list[int] = field(default_factory=list)
    error: list[BaseException] = field(default_factory=list)
    thread: threading.Thread | None = None

    def start(self, **kwargs: object) -> None:
        def run() -> None:
            try:
                self.result.append(
                    sniff(self.endpoint, out=self.lines.put, stop=self.stop, ready=self.ready, **kwargs)  # type: ignore[arg-type]
                )
            except BaseException as exc:
                self.error.append(exc)
                self.ready.set()

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()
        assert self.ready.wait(TIMEOUT), "sniffer did not subscribe"
        assert not self.error, self.error

    def next(self) -> str:
        try:
            return self.lines.get(timeout=TIMEOUT)
        except queue.Empty:
            raise AssertionError("no output from the sniffer") from None

    def finish(self) -> int:
        self.stop.set()
        assert self.thread is not None
        self.thread.join(TIMEOUT)
        assert not self.thread.is_alive() and not self.error, self.error
        return self.result[0]


def put(session: zenoh.Session, channel: str, msg: Communicate) -> None:
    assert msg.sender is not None
    session.put(keys.fipa_key(channel, msg.sender.name, msg.receiver[0].name), encode(msg))


def sync(sniffer: Sniffer, session: zenoh.Session, probe: Communicate) -> int:
    """Publish ``probe`` (reply-with ``probe-<n>``) until the sniffer prints it: the route
    router → sniffer is then in place. Returns the number of probes printed so far."""
    for n in range(50):
        put(session, "C4", msgspec.structs.replace(probe, reply_with=f"probe-{n}"))
        try:
            line = sniffer.lines.get(timeout=0.2)
        except queue.Empty:
            continue
        assert ":reply-with probe-" in line, line
        return 1
    raise AssertionError("the sniffer never printed a probe")


def collect(sniffer: Sniffer, session: zenoh.Session, probe: Communicate) -> tuple[list[str], int]:
    """Publish a sentinel (the probe with reply-with ``sentinel``) and return the lines printed
    before it that are not probes, and the number of probe and sentinel lines seen."""
    put(session, "C4", msgspec.structs.replace(probe, reply_with="sentinel"))
    lines: list[str] = []
    probes = 0
    while True:
        line = sniffer.next()
        if ":reply-with sentinel" in line:
            return lines, probes + 1
        if ":reply-with probe-" in line:
            probes += 1
        else:
            lines.append(line)


def test_filters_by_agent_channel_and_performative_with_readable_content(
    router: str, publisher: zenoh.Session
) -> None:
    sniffer = Sniffer(router)
    sniffer.start(
        agents={"a_pl"}, channels={"C4", "C3"}, performatives={"query-ref", "inform"}, conversation=None
    )
    probe = comm("query-ref", "a_pl", "a_km", ObjectQuery("probe"))
    probes = sync(sniffer, publisher, probe)
    shown = [
        ("C4", comm("query-ref", "a_pl", "a_km", ObjectQuery("jar"), conversation="q1")),
        ("C4", comm("inform", "a_km", "a_pl", Answer(), conversation="q1")),
        ("C3", comm("inform", "a_pl", "a_co", conversation="p1")),
    ]
    hidden = [
        ("C4", comm("failure", "a_km", "a_pl", conversation="q2")),  # performative
        ("C1", comm("inform", "a_ta", "a_co", conversation="x1")),  # channel and agent
        ("C6", comm("query-ref", "a_ta", "a_km", ObjectQuery("jar"))),  # channel and agent
    ]
    for channel, msg in [hidden[0], shown[0], hidden[1], shown[1], hidden[2], shown[2]]:
        put(publisher, channel, msg)
    lines, more = collect(sniffer, publisher, probe)
    assert sniffer.finish() == len(shown) + probes + more
    assert len(lines) == len(shown), lines
    for line, (channel, msg) in zip(lines, shown, strict=True):
        head, body = line.split("\n", 1)
        match = HEADER.match(head)
        assert match is not None, head
        assert msg.sender is not None
        assert match.groups() == (channel, msg.sender.name, msg.receiver[0].name, str(len(encode(msg))))
        assert body.startswith(
            f"({msg.performative.value}\n :sender (agent-identifier :name {msg.sender.name})"
        )
        assert f":conversation-id {msg.conversation_id}" in body
    # the content is the decoded term as compact JSON, not msgpack octets
    assert ':content "{\\"type\\":\\"object\\",\\"name\\":\\"jar\\"}"' in lines[0]
    assert ":language L_WM" in lines[0]
    assert ":content" not in lines[2]  # no content, none printed


def test_conversation_filter_and_raw_string_form_parses_back(router: str, publisher: zenoh.Session) -> None:
    sniffer = Sniffer(router)
    sniffer.start(agents=None, channels=None, performatives=None, conversation="c-keep", content=False)
    probe = comm("query-ref", "a_pl", "a_km", ObjectQuery("probe"), conversation="c-keep")
    probes = sync(sniffer, publisher, probe)
    kept = [
        ("C4", comm("query-ref", "a_pl", "a_km", ObjectQuery("jar"), conversation="c-keep", reply_with="r1")),
        ("C4", comm("inform", "a_km", "a_pl", Answer(), conversation="c-keep")),
    ]
    put(publisher, "C4", comm("query-ref", "a_pl", "a_km", ObjectQuery("bowl"), conversation="c-other"))
    put(publisher, *kept[0])
    put(publisher, "C4", comm("inform", "a_km", "a_pl", Answer(), conversation="c-keep-not"))
    put(publisher, *kept[1])
    lines, more = collect(sniffer, publisher, probe)
    assert sniffer.finish() == len(kept) + probes + more
    assert len(lines) == len(kept), lines
    for line, (_, msg) in zip(lines, kept, strict=True):
        head, body = line.split("\n", 1)
        assert HEADER.match(head)
        assert parse(body) == msg  # the exact SC00070 string form, content octets included


def test_a_batch_is_printed_communicate_by_communicate(router: str, publisher: zenoh.Session) -> None:
    sniffer = Sniffer(router)
    sniffer.start(agents=None, channels=None, performatives=None, conversation=None, content=False)
    probe = comm("query-ref", "a_pl", "a_km", ObjectQuery("probe"))
    probes = sync(sniffer, publisher, probe)
    sent = [comm("inform", "a_km", "a_pl", Answer(), conversation=f"c-{i}") for i in range(3)]
    publisher.put(keys.fipa_key("C4", "a_km", "a_pl"), pack([encode(m) for m in sent]))  # one step's put
    lines, more = collect(sniffer, publisher, probe)
    assert sniffer.finish() == len(sent) + probes + more
    assert [parse(line.split("\n", 1)[1]) for line in lines] == sent


def test_malformed_payloads_are_one_line_and_the_sniffer_goes_on(
    router: str, publisher: zenoh.Session
) -> None:
    sniffer = Sniffer(router)
    sniffer.start(agents=None, channels={"C4"}, performatives=None, conversation=None)
    probe = comm("query-ref", "a_pl", "a_km", ObjectQuery("probe"))
    probes = sync(sniffer, publisher, probe)
    publisher.put(keys.fipa_key("C4", "a_pl", "a_km"), b"\xc1not msgpack")
    publisher.put(keys.fipa_key("C1", "a_co", "a_ta"), b"\xc1filtered out by channel")
    good = comm("query-ref", "a_pl", "a_km", ObjectQuery("jar"))
    put(publisher, "C4", good)
    lines, more = collect(sniffer, publisher, probe)
    assert sniffer.finish() == 1 + probes + more  # the malformed line is not a communicate
    assert len(lines) == 2, lines
    bad, after = lines
    assert "\n" not in bad
    assert HEADER.match(bad)
    assert re.search(r"  C4  a_pl → a_km  \(12 B\)  malformed payload: .+", bad), bad
    assert after.split("\n", 1)[1].startswith("(query-ref")


def test_malformed_key_is_reported_without_channel_or_agent_filters(
    router: str, publisher: zenoh.Session
) -> None:
    sniffer = Sniffer(router)
    sniffer.start(agents=None, channels=None, performatives=None, conversation=None)
    probe = comm("query-ref", "a_pl", "a_km", ObjectQuery("probe"))
    sync(sniffer, publisher, probe)
    publisher.put("roco/fipa/C4/a_pl", encode(probe))
    lines, _ = collect(sniffer, publisher, probe)
    sniffer.finish()
    assert len(lines) == 1 and "roco/fipa/C4/a_pl" in lines[0] and "malformed key" in lines[0]


def test_bad_filters_raise_before_connecting() -> None:
    stop = threading.Event()
    with pytest.raises(ValueError, match="unknown performative 'query-reff'"):
        sniff(
            f"tcp/127.0.0.1:{free_port()}",
            agents=None,
            channels=None,
            performatives={"query-reff"},
            conversation=None,
            out=print,
            stop=stop,
        )


def test_no_router_raises() -> None:
    with pytest.raises(zenoh.ZError):
        sniff(
            f"tcp/127.0.0.1:{free_port()}",
            agents=None,
            channels=None,
            performatives=None,
            conversation=None,
            out=print,
            stop=threading.Event(),
        )


def test_parse_filters_normalises_and_names_what_is_unknown() -> None:
    f = parse_filters(agents=["a_pl"], channels=["c4", "C1"], performatives=["QUERY-REF"], conversation="x")
    assert f == Filters(
        agents=frozenset({"a_pl"}),
        channels=frozenset({"C1", "C4"}),
        performatives=frozenset({"query-ref"}),
        conversation="x",
    )
    assert parse_filters(agents=[], channels=None, performatives=()) == Filters()
    spec = default_spec()
    new = f"C{len(spec.channels) + 1}"  # no channel of the specification (C9 in the shipped one)
    with pytest.raises(ValueError) as err:
        parse_filters(channels=[new, "C4"], performatives=["ask", "inform"], agents=["a_xx"])
    text = str(err.value)
    assert f"unknown channel '{new}' (known: {', '.join(c.name for c in spec.channels)})" in text
    assert "unknown performative 'ask' (known: accept-proposal, agree," in text
    assert f"unknown agent 'a_xx' (known: {', '.join(spec.agent_names)})" in text
    with pytest.raises(ValueError, match=f"unknown channels 'C0', '{new}'"):
        parse_filters(channels=["C0", new])
    # an agent of another platform plays the external role: it may be named
    assert parse_filters(agents=["da0@host:1099/JADE"]).agents == frozenset({"da0@host:1099/JADE"})
    with pytest.raises(ValueError, match="empty conversation-id"):
        parse_filters(conversation=" ")


def test_filters_match_either_end_of_key_or_communicate() -> None:
    msg = comm("inform", "a_km", "a_pl", Answer())
    assert Filters(agents=frozenset({"a_km"})).passes("C4", "a_km", "a_pl", msg)
    assert Filters(agents=frozenset({"a_pl"})).passes("C4", "a_km", "a_pl", msg)
    assert not Filters(agents=frozenset({"a_co"})).passes("C4", "a_km", "a_pl", msg)
    assert not Filters(channels=frozenset({"C3"})).passes("C4", "a_km", "a_pl", msg)
    assert not Filters(performatives=frozenset({"failure"})).passes("C4", "a_km", "a_pl", msg)
    assert not Filters(conversation="c-").passes("C4", "a_km", "a_pl", msg)  # exact, not a prefix
    assert Filters(conversation="c-1").passes("C4", "a_km", "a_pl", msg)


def test_render_readable_escapes_control_characters_and_raw_is_exact() -> None:
    msg = msgspec.structs.replace(
        comm("inform", "a_km", "a_pl", conversation="c\x1b[31m"), content=b"\x00\x1b\x9b\xff"
    )
    readable = render(msg)
    assert "\x1b" not in readable and "\\x1b" in readable
    assert ':content "<4 bytes, base64 ABub/w==>"' in readable  # binary content that is no term
    assert ':conversation-id "c\\x1b[31m"' in readable  # text is a literal, its ESC escaped
    assert parse(render(msg, content=False)) == msg
