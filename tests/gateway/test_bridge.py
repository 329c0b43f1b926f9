"""The ACL gateway (services/gateway/bridge.py) between a JADE-like platform over HTTP (FIPA
SC00084) and a_hi on a MemoryBus with a stand-in a_co: a foreign agent's sentence reaches a_hi
as a person's would and its answers come back; what the specification does not allow is refused
with a FIPA refuse or not-understood and counted."""

from __future__ import annotations

import json
import logging
import queue
import time
from collections.abc import Iterator
from dataclasses import dataclass

import msgspec
import pytest

from services.fleet.launcher import free_port
from services.gateway.bounds import Limits
from services.gateway.bridge import GATEWAY, Gateway, open_gateway
from services.gateway.envelope import Envelope
from services.gateway.http_mtp import MTPMessage
from services.gateway.server import Refused
from services.runtime import keys
from services.runtime.human import ReportKind
from services.runtime.memory_transport import MemoryBus
from services.spec.model import default_spec
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, SentenceReport, TaskAtom
from shared.fipa_codec.string_form import parse
from tests.agents.human_interface.test_agent import TIMEOUT, ScriptedCo, Stage
from tests.support.jade_platform import JADE, JadePlatform, envelope_xml, jade_body, post


@dataclass
class Bridge:
    stage: Stage
    co: ScriptedCo
    gateway: Gateway
    url: str
    jade: JadePlatform


@pytest.fixture
def bridge() -> Iterator[Bridge]:
    stage = Stage()
    co = stage.co()
    stage.start_hi()
    assert co.subscribed.wait(TIMEOUT)
    port = free_port()
    url = f"http://127.0.0.1:{port}/acc"
    gateway, server = open_gateway(stage.bus.transport(), default_spec(), "127.0.0.1", port, url)
    jade = JadePlatform()
    try:
        yield Bridge(stage, co, gateway, url, jade)
    finally:
        jade.close()
        server.stop()
        gateway.stop()
        stage.stop()


def sentence(text: str) -> str:
    return json.dumps({"type": "sentence", "text": text})


def report(content: bytes) -> SentenceReport:
    return msgspec.json.decode(content, type=SentenceReport)


@pytest.mark.requirement("R1.4")
def test_a_foreign_request_reaches_a_hi_as_a_persons_command_and_its_answers_return(b: Bridge) -> None:
    status = b.jade.request(b.url, "a_hi", b.jade.acl("a_hi", sentence("bring me the cup"), "C1_jade"))
    assert status == 200
    request = b.co.receive(Performative.REQUEST)  # a_hi read it and asked a_co, as for a person
    assert isinstance(request.content, HumanCommand) and request.content.goal == TaskAtom("bring", ("cup",))
    cid = request.msg.conversation_id or ""

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.engine.reply(
            request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True, detail="done")
        )

    b.co.do(run)
    agree, inform = b.jade.next(), b.jade.next()
    for answer in (agree, inform):
        assert answer.msg.sender is not None and answer.msg.sender.name == "a_hi"
        assert answer.msg.sender.addresses == (b.url,)  # the next message comes back through the gateway
        assert answer.msg.conversation_id == "C1_jade" and answer.msg.in_reply_to == "C1_jade-r1"
        assert answer.msg.receiver[0].name == JADE and answer.envelope.findtext(".//to//name") == JADE
    assert agree.msg.performative is Performative.AGREE
    assert report(agree.msg.content).kind == ReportKind.ACCEPTED
    assert inform.msg.performative is Performative.INFORM
    outcome = report(inform.msg.content)
    assert outcome.kind == ReportKind.SUCCEEDED and outcome.text.endswith(": succeeded; done")
    # on the bus, under the JADE agent's own name (what the recorder and roco sniff see)
    key = keys.fipa_key("C8", JADE, "a_hi")
    (payload,) = [p for k, p in b.stage.bus.published if k == key]
    assert decode(payload).sender.name == JADE  # type: ignore[union-attr]
    assert b.gateway.counters["forwarded"] == 1 and b.gateway.counters["answered"] == 2


@pytest.mark.requirement("R1.4")
def test_a_sentence_a_hi_does_not_understand_is_refused_by_a_hi(b: Bridge) -> None:
    assert b.jade.request(b.url, "a_hi", b.jade.acl("a_hi", sentence("sing me a song"), "C2_jade")) == 200
    answer = b.jade.next()
    assert answer.msg.performative is Performative.REFUSE
    assert report(answer.msg.content).kind == ReportKind.NOT_UNDERSTOOD


def test_a_request_to_an_agent_it_may_not_address_is_refused_and_counted(b: Bridge) -> None:
    assert b.jade.request(b.url, "a_co", b.jade.acl("a_co", sentence("bring me the cup"), "C3_jade")) == 200
    answer = b.jade.next()
    assert answer.msg.performative is Performative.REFUSE
    assert answer.msg.sender is not None and answer.msg.sender.name == "a_co"
    assert answer.msg.in_reply_to == "C3_jade-r1" and b"may not address a_co" in answer.msg.content
    assert b.gateway.counters["refused"] == 1 and b.gateway.counters["refused.receiver"] == 1
    assert not [
        k for k, _ in b.stage.bus.published if k.startswith(keys.FIPA_PREFIX) and JADE.split("/")[0] in k
    ]


@pytest.mark.parametrize(
    ("content", "performative", "reason"),
    [
        ("bring me the cup", "REQUEST", "content"),  # not the JSON of an L_HC term
        (json.dumps({"type": "status_query"}), "REQUEST", "content"),  # an L_HC term C8 does not carry
        (sentence("bring me the cup"), "QUERY-REF", "not_in_interface"),
    ],
)
def test_what_the_channel_does_not_allow_is_not_understood(
    b: Bridge, content: str, performative: str, reason: str
) -> None:
    acl = b.jade.acl("a_hi", content, "C4_jade", performative=performative)
    assert b.jade.request(b.url, "a_hi", acl) == 200
    answer = b.jade.next()
    assert answer.msg.performative is Performative.NOT_UNDERSTOOD
    assert b.gateway.counters[f"refused.{reason}"] == 1


def test_bad_bodies_get_406_and_the_gateway_keeps_going(b: Bridge) -> None:
    assert post(b.url, b"not a message", "text/plain") == 406
    assert b.jade.request(b.url, "a_hi", "(request :sender") == 406  # no ACL message
    assert b.jade.request(b.url, "a_hi", b.jade.acl("a_hi", sentence("sing"), "C5_jade")) == 200
    assert b.jade.next().msg.performative is Performative.REFUSE
    assert b.gateway.counters["http.406"] == 2


@pytest.fixture
def b(bridge: Bridge) -> Bridge:
    return bridge


def test_a_payload_in_another_character_set_is_read_in_it() -> None:
    """The envelope's payload-encoding (ISO-8859-1 here) says how the payload's text is written."""
    from services.gateway.envelope import Envelope
    from services.gateway.http_mtp import MTPError, MTPMessage
    from services.runtime.memory_transport import MemoryBus
    from shared.fipa_codec import AgentIdentifier

    posted: queue.SimpleQueue[tuple[str, MTPMessage]] = queue.SimpleQueue()

    async def post(address: str, message: MTPMessage) -> None:
        posted.put((address, message))

    gateway = Gateway(MemoryBus().transport(), default_spec(), "http://127.0.0.1:1/acc", post=post)
    gateway.start()
    try:
        acl = (
            f"(request :sender (agent-identifier :name {JADE} :addresses (sequence http://jade:7778/acc)) "
            f':receiver (set (agent-identifier :name a_co)) :content "caf\u00e9" :reply-with r1)'
        )
        to = (AgentIdentifier("a_co"),)
        gateway.deliver(
            MTPMessage(Envelope(to=to, payload_encoding="ISO-8859-1"), acl.encode("latin-1")), "1.2.3.4"
        )
        address, message = posted.get(timeout=TIMEOUT)
        assert address == "http://jade:7778/acc" and b"(refuse" in message.payload
        with pytest.raises(MTPError, match="payload-encoding 'no-such-charset' is not read here"):
            gateway.deliver(
                MTPMessage(Envelope(to=to, payload_encoding="no-such-charset"), b"(x)"), "1.2.3.4"
            )
    finally:
        gateway.stop()


def test_a_foreign_agent_s_notice_reaches_the_person_with_its_name(b: Bridge) -> None:
    """An agent of another platform tells the person something (roco-notify on C8, an inform of
    an L_HC Notice): a_hi passes it on as a notice report naming the foreign agent; nothing
    answers it."""
    notice = json.dumps({"type": "notice", "text": "the jar tipped over", "severity": "warning"})
    acl = b.jade.acl("a_hi", notice, "N1_jade", performative="INFORM").replace(
        ":protocol  fipa-request", ":protocol  roco-notify"
    )
    assert b.jade.request(b.url, "a_hi", acl) == 200
    told = b.stage.person.next("")
    assert (told.kind, told.sender, told.severity, told.text) == (
        ReportKind.NOTICE,
        JADE,
        "warning",
        "the jar tipped over",
    )


def test_a_ros2_callers_name_is_no_sender_the_gateway_speaks_for(b: Bridge) -> None:
    """Names ``…@ros2`` play x_ros2, served by roco ros2 on C9 (docs/ros2.md): over HTTP the
    gateway answers 403 and puts nothing on Zenoh."""
    caller = "c00ff@ros2"
    payload = b.jade.acl("a_hi", sentence("bring me the cup"), "C9_ros2").replace(JADE, caller).encode()
    body = jade_body(envelope_xml("a_hi", caller, b.jade.address, len(payload)), payload)
    assert post(b.url, body) == 403
    assert b.gateway.counters["refused.sender"] == 1
    assert not [k for k, _ in b.stage.bus.published if k.startswith(keys.FIPA_PREFIX) and "ros2" in k]


# ---- conversations followed through their protocol (services/gateway/conversations.py) --------
# A Gateway without HTTP: messages handed to ``deliver`` as the HTTP server would, a_hi's
# communicates put on the MemoryBus, answers taken by a stand-in ``post``.

FOREIGN_ADDRESS = "http://jade:7778/acc"


@dataclass
class Direct:
    gateway: Gateway
    bus: MemoryBus
    posted: queue.SimpleQueue[tuple[str, MTPMessage]]
    reports: queue.SimpleQueue[bytes]

    def deliver(
        self,
        performative: str,
        conversation: str | None,
        reply_with: str,
        *,
        content: str | None = None,
        protocol: str = "fipa-request",
        peer: str = "1.2.3.4",
    ) -> None:
        """A message from the JADE agent to a_hi, as the HTTP server hands it over."""
        parts = [
            f"({performative} :sender (agent-identifier :name {JADE}",
            f" :addresses (sequence {FOREIGN_ADDRESS}))",
            " :receiver (set (agent-identifier :name a_hi))",
        ]
        if content is not None:
            quoted = content.replace('"', '\\"')
            parts.append(f' :content "{quoted}" :language L_HC :ontology O_RoCo')
        parts.append(f" :protocol {protocol} :reply-with {reply_with}")
        if conversation is not None:
            parts.append(f" :conversation-id {conversation}")
        acl = "".join(parts) + ")"
        self.gateway.deliver(MTPMessage(Envelope(to=(AgentIdentifier("a_hi"),)), acl.encode()), peer)

    def say(self, performative: Performative, conversation: str, in_reply_to: str, kind: str) -> None:
        """a_hi's communicate to the JADE agent, put on Zenoh where the gateway hears it."""
        name, data = encode_content(SentenceReport(kind=kind, text=kind))
        msg = Communicate(
            performative=performative,
            sender=AgentIdentifier("a_hi"),
            receiver=(AgentIdentifier(JADE),),
            content=data,
            language=name,
            ontology="O_RoCo",
            encoding="msgpack",
            protocol="fipa-request",
            conversation_id=conversation,
            in_reply_to=in_reply_to,
        )
        self.bus.publish(keys.fipa_key("C8", "a_hi", JADE), encode(msg))

    def settled(self) -> None:
        """Return once the gateway has handled everything given to it so far (it handles its
        inputs in order, and answers the counters' request among them) and posted what it
        answered."""
        self.bus.publish(keys.COUNTERS_ASK, b"")
        self.reports.get(timeout=TIMEOUT)
        deadline = time.monotonic() + TIMEOUT
        while self.gateway.poster.outstanding() and time.monotonic() < deadline:
            time.sleep(0.005)
        assert not self.gateway.poster.outstanding()

    def answers(self) -> list[Communicate]:
        """The ACL messages posted to the JADE agent so far."""
        out = []
        while not self.posted.empty():
            address, message = self.posted.get_nowait()
            assert address == FOREIGN_ADDRESS
            out.append(parse(message.payload))
        return out

    def put_by_jade(self) -> list[Communicate]:
        """What the gateway put on Zenoh as the JADE agent."""
        key = keys.fipa_key("C8", JADE, "a_hi")
        return [decode(p) for k, p in self.bus.published if k == key]


@pytest.fixture
def direct() -> Iterator[Direct]:
    bus = MemoryBus()
    posted: queue.SimpleQueue[tuple[str, MTPMessage]] = queue.SimpleQueue()
    reports: queue.SimpleQueue[bytes] = queue.SimpleQueue()

    async def post(address: str, message: MTPMessage) -> None:
        posted.put((address, message))

    bus.subscribe(keys.counters_key(GATEWAY), lambda _key, payload: reports.put(payload))
    limits = Limits(linger_s=0.0)  # a name is free as soon as its conversations are over
    gateway = Gateway(bus.transport(), default_spec(), "http://127.0.0.1:1/acc", limits=limits, post=post)
    gateway.bind()
    gateway.start()
    try:
        yield Direct(gateway, bus, posted, reports)
    finally:
        gateway.stop()


def test_the_same_request_again_in_one_conversation_is_not_understood(direct: Direct) -> None:
    """A conversation-id names one conversation (FIPA SC00061): a second request in it, under a
    reply-with of its own, is no retransmission but a protocol violation (FIPA SC00026): refused
    not-understood with the state machine's reason, counted, not put on Zenoh. The request sent
    again under its own reply-with (a retransmission) passes, for a_hi to answer as a copy."""
    words = sentence("bring me the cup")
    direct.deliver("REQUEST", "D1", "D1-r1", content=words)
    direct.deliver("REQUEST", "D1", "D1-r2", content=words)
    direct.deliver("REQUEST", "D1", "D1-r1", content=words)  # the first again: a copy
    direct.settled()
    put = direct.put_by_jade()
    assert [(m.performative, m.reply_with) for m in put] == [
        (Performative.REQUEST, "D1-r1"),
        (Performative.REQUEST, "D1-r1"),
    ]
    key = keys.fipa_key("C8", JADE, "a_hi")
    first, again = [p for k, p in direct.bus.published if k == key]
    assert first == again  # byte for byte: a copy to a_hi (services/runtime/dedup.py)
    (answer,) = direct.answers()
    assert answer.performative is Performative.NOT_UNDERSTOOD
    assert answer.sender is not None and answer.sender.name == "a_hi"
    assert (answer.conversation_id, answer.in_reply_to) == ("D1", "D1-r2")
    assert b"may not send 'request'" in answer.content and b"new conversation-id" in answer.content
    counters = direct.gateway.counters
    assert counters["refused.protocol_state"] == 1 and counters["refused"] == 1
    assert counters["forwarded"] == 2
    # a_hi's conversation is still open: the name stays bound to its peer
    with pytest.raises(Refused):
        direct.deliver("REQUEST", "D9", "D9-r1", content=words, peer="5.6.7.8")


def test_a_request_without_conversation_id_is_not_understood(direct: Direct) -> None:
    """roco follows each conversation by its conversation-id (FIPA SC00061 leaves it optional):
    a request without one is refused at the gateway, as a_hi would refuse it."""
    direct.deliver("REQUEST", None, "D2-r1", content=sentence("bring me the cup"))
    direct.settled()
    assert direct.put_by_jade() == []
    (answer,) = direct.answers()
    assert answer.performative is Performative.NOT_UNDERSTOOD and b"needs a conversation-id" in answer.content
    assert direct.gateway.counters["refused.protocol_state"] == 1


def test_a_not_understood_from_one_that_received_nothing_is_refused_unanswered(direct: Direct) -> None:
    """not-understood answers a communicate received (FIPA SC00037 §3.12): from the foreign
    agent before a_hi said anything in the conversation it is refused, counted and not put on
    Zenoh, and not answered (no answers to answers). One in a conversation the gateway does not
    know goes on to a_hi, as any agent takes one of a conversation it may have forgotten
    (services/runtime/protocol_state.py ``judge``)."""
    direct.deliver("REQUEST", "D3", "D3-r1", content=sentence("bring me the cup"))
    direct.deliver("NOT-UNDERSTOOD", "D3", "D3-r2")  # a_hi has not answered yet
    direct.deliver("NOT-UNDERSTOOD", "D4", "D4-r1")  # nothing the gateway knows in D4
    direct.settled()
    assert [m.performative for m in direct.put_by_jade()] == [
        Performative.REQUEST,
        Performative.NOT_UNDERSTOOD,
    ]
    assert direct.answers() == []
    counters = direct.gateway.counters
    assert counters["refused.protocol_state"] == 1 and counters["forwarded"] == 2
    assert not direct.gateway.conversations.ended(JADE, "a_hi", "fipa-request", "D3")


def test_an_agents_inform_after_the_conversation_ended_is_dropped(
    direct: Direct, caplog: pytest.LogCaptureFixture
) -> None:
    """a_hi refuses the request, which ends the conversation (FIPA SC00026); an inform after
    that is out of the protocol: dropped, counted ``dropped.out_of_protocol``, one WARNING line,
    not posted. So is an inform in a conversation the gateway never bridged."""
    direct.deliver("REQUEST", "D5", "D5-r1", content=sentence("sing me a song"))
    direct.settled()
    direct.say(Performative.REFUSE, "D5", "D5-r1", "not-understood")
    direct.settled()
    assert [m.performative for m in direct.answers()] == [Performative.REFUSE]
    with caplog.at_level(logging.WARNING, logger=GATEWAY):
        direct.say(Performative.INFORM, "D5", "D5-r1", "succeeded")
        direct.say(Performative.INFORM, "D6", "D6-r1", "succeeded")
        direct.settled()
    assert direct.answers() == []
    counters = direct.gateway.counters
    assert counters["dropped.out_of_protocol"] == 2 and counters["answered"] == 1
    lines = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    dropped = [line for line in lines if line.startswith("dropped inform from a_hi")]
    assert len(dropped) == 2 and "D5" in dropped[0] and "already ended" in dropped[0]
    assert all("\n" not in line for line in dropped)


def test_a_legal_request_agree_inform_goes_through_and_frees_the_conversation(direct: Direct) -> None:
    """request → agree → inform, as fipa-request allows (FIPA SC00026): each passes; after the
    agree the conversation is open (the name stays bound to its peer), after the inform it is
    over (its tracker finished) and the name is free for another peer."""
    words = sentence("bring me the cup")
    direct.deliver("REQUEST", "D7", "D7-r1", content=words)
    direct.settled()
    direct.say(Performative.AGREE, "D7", "D7-r1", "accepted")
    direct.settled()
    conversations = direct.gateway.conversations
    assert not conversations.ended(JADE, "a_hi", "fipa-request", "D7")
    with pytest.raises(Refused):  # another peer, while the conversation is open
        direct.deliver("REQUEST", "D8", "D8-r1", content=words, peer="5.6.7.8")
    direct.say(Performative.INFORM, "D7", "D7-r1", "succeeded")
    direct.settled()
    assert [m.performative for m in direct.answers()] == [Performative.AGREE, Performative.INFORM]
    assert conversations.ended(JADE, "a_hi", "fipa-request", "D7")
    assert conversations.states.open_count == 0
    counters = direct.gateway.counters
    assert counters["forwarded"] == 1 and counters["answered"] == 2
    assert counters["refused.identity"] == 1  # the other peer's only
    assert {k for k in counters if k.startswith(("refused.", "dropped."))} == {"refused.identity"}
    time.sleep(0.01)  # linger_s 0: over as soon as the clock moves
    direct.deliver("REQUEST", "D8", "D8-r1", content=words, peer="5.6.7.8")  # the name is free


def test_a_notice_ends_its_conversation_at_once(direct: Direct) -> None:
    """roco-notify is one inform that nothing answers: its conversation is over once it is
    put on Zenoh, and the foreign name is free again (not held until ``conversation_s``)."""
    notice = json.dumps({"type": "notice", "text": "the jar tipped over"})
    direct.deliver("INFORM", "N2", "N2-r1", content=notice, protocol="roco-notify")
    direct.settled()
    assert [m.protocol for m in direct.put_by_jade()] == ["roco-notify"]
    time.sleep(0.01)  # linger_s 0: over as soon as the clock moves
    direct.deliver("INFORM", "N3", "N3-r1", content=notice, protocol="roco-notify", peer="5.6.7.8")
    assert direct.gateway.conversations.ended(JADE, "a_hi", "roco-notify", "N2")
