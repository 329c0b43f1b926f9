"""The ACL gateway (services/gateway/bridge.py) between a JADE-like platform over HTTP (FIPA
SC00084) and a_hi on a MemoryBus with a stand-in a_co: a foreign agent's sentence reaches a_hi
as a person's would and its answers come back; what the specification does not allow is refused
with a FIPA refuse or not-understood and counted."""

from __future__ import annotations

import json
import queue
from collections.abc import Iterator
from dataclasses import dataclass

import msgspec
import pytest

from services.fleet.launcher import free_port
from services.gateway.bridge import Gateway, open_gateway
from services.runtime import keys
from services.runtime.human import ReportKind
from services.spec.model import default_spec
from shared.fipa_codec import Performative, decode
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, SentenceReport, TaskAtom
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
        co.reply(request, Performative.AGREE)
        co.reply(request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True, detail="done"))

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
