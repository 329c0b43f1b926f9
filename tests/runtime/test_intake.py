"""The checks of a received communicate against the agent's interface
(services/runtime/intake.py): each refusal names its reason in words and the counter it is
counted under; what passes comes with its decoded content. Pure: no agent."""

from __future__ import annotations

from services.runtime.intake import Refusal, content_of, interface_refusal
from services.spec.model import MessageKind
from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import Subscription

SW = MessageKind("C1", "a_ta", "a_co", "inform", "coordinate", ("L_SW",), ("SWStatus",))
STATUS = SWStatus(state=SWState.RUNNING, plan_id="p")


def inform(
    content: bytes = b"",
    language: str | None = "L_SW",
    *,
    ontology: str = "O_RoCo",
    performative: Performative = Performative.INFORM,
    encoding: str | None = None,
) -> Communicate:
    return Communicate(
        performative=performative,
        sender=AgentIdentifier("a_ta"),
        receiver=(AgentIdentifier("a_co"),),
        content=content,
        language=language,
        ontology=ontology if language else None,
        encoding=encoding,
        protocol="coordinate",
        conversation_id="c",
    )


def test_the_sender_must_be_the_keys_and_the_kind_the_interfaces_on_that_channel() -> None:
    msg = inform()
    assert interface_refusal("a_ta", "C1", msg, SW) is None
    assert interface_refusal("a_pl", "C1", msg, SW) == Refusal(
        "sender does not match the key it came on", "sender_mismatch"
    )
    assert interface_refusal("a_ta", "C2", msg, SW) == Refusal(
        "unexpected inform in protocol coordinate on C2", "not_in_interface"
    )
    assert interface_refusal("a_ta", "C1", msg, None) is not None


def test_a_term_of_the_kind_is_decoded() -> None:
    _, data = encode_content(STATUS)
    assert content_of(inform(data), SW) == (STATUS, None)


def test_language_ontology_content_and_term_are_each_refused_with_their_counter() -> None:
    _, data = encode_content(STATUS)
    refused = {
        "language": inform(data, language="L_WM"),
        "ontology": inform(data, ontology="O_Other"),
        "content": inform(b"\xc1not msgpack"),
    }
    for counter, msg in refused.items():
        content, refusal = content_of(msg, SW)
        assert content is None and refusal is not None and refusal.counter == counter, (counter, refusal)
    _, other = encode_content(Subscription())
    wm = MessageKind("C6", "a_km", "a_ta", "inform", "coordinate", ("L_SW", "L_WM"), ("SWStatus",))
    _, refusal = content_of(inform(other, language="L_WM"), wm)
    assert refusal == Refusal("inform in coordinate may carry SWStatus, not Subscription", "content_type")


def test_a_reason_in_plain_text_and_an_empty_content_are_not_decoded() -> None:
    failure = inform(b"it broke", language=None, performative=Performative.FAILURE, encoding="utf-8")
    assert content_of(failure, SW) == (None, None)
    assert content_of(inform(b""), SW) == (None, None)
