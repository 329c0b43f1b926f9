"""The message envelope of the FIPA agent message transport in XML (FIPA SC00085), as JADE's
HTTP MTP writes and reads it.

Layout (SC00085 §2; the order of JADE 4.6's ``jade.mtp.http.XMLCodec.encodeXML``)::

    <?xml version="1.0"?>
    <envelope><params index="1">
      <to><agent-identifier><name>a_hi</name>
          <addresses><url>http://host:7778/acc</url></addresses></agent-identifier></to>  (1..n)
      <from><agent-identifier>…</agent-identifier></from>                            (0..1)
      <comments>…</comments>                                                        (0..1)
      <acl-representation>fipa.acl.rep.string.std</acl-representation>
      <payload-length>312</payload-length>
      <payload-encoding>US-ASCII</payload-encoding>
      <date>20261122T201900000Z</date>
      <intended-receiver><agent-identifier>…</agent-identifier></intended-receiver>  (0..n)
    </params></envelope>

Reading: several ``params`` elements may follow one another (SC00085: each transport hop adds
one with a higher ``index``); a parameter of a later one replaces the earlier one's (the
receivers: a later ``to`` list replaces the earlier list). ``received`` stamps and
``user-defined`` properties are read over and not kept; ``resolvers`` of an agent identifier
are not read either (roco resolves no names). Tags are compared without case, as JADE's SAX
handler does. Writing escapes ``<``, ``&`` and ``>`` in text (JADE writes text as it is, which
an XML reader may refuse for a name holding ``&``).

Reading is bounded: a document over ``max_size`` octets is refused before it is parsed; the
XML reader (defusedxml over the standard library's expat) refuses a document type declaration
(DTD) where it starts, and with it every entity definition, internal or external; numbers
(``payload-length``, ``params index``) longer than ``max_digits`` digits are refused unread.

Errors: :class:`EnvelopeError` (a ValueError), one line: over the size limit, not XML, a DTD,
not an ``envelope``, no receiver, an agent identifier without a name or with a name or address
that is no FIPA SC00070 word, a payload length or params index that is not a number of at
most ``max_digits`` digits.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, replace

import defusedxml
import defusedxml.ElementTree as SafeET

from services.gateway.bounds import DEFAULT_LIMITS, BoundError, read_digits
from shared.fipa_codec.aid import AgentIdentifier

__all__ = ["STRING_REPRESENTATION", "Envelope", "EnvelopeError", "parse_xml", "to_xml"]

MAX_ENVELOPE = DEFAULT_LIMITS.max_envelope
MAX_DIGITS = DEFAULT_LIMITS.max_digits

STRING_REPRESENTATION = "fipa.acl.rep.string.std"
"""The ``acl-representation`` of the FIPA ACL string form (FIPA SC00070), the one roco reads
and writes."""


class EnvelopeError(ValueError):
    """An XML envelope (FIPA SC00085) roco cannot read; the message says why, in one line."""


@dataclass(frozen=True)
class Envelope:
    """The transport parameters of one message (FIPA SC00067 §4.1, XML: SC00085).

    ``to``: the agents it is for; ``from_``: who sends it (its addresses are where an answer
    may go); ``acl_representation``: how the payload is written (:data:`STRING_REPRESENTATION`);
    ``payload_length`` (octets) and ``payload_encoding`` (a character set, ``US-ASCII`` or
    ``UTF-8``); ``date``: when it was sent, as written (SC00070 ``DateTime``);
    ``intended_receiver``: the agents this copy is for when the transport changed ``to``;
    ``comments``: free text."""

    to: tuple[AgentIdentifier, ...]
    from_: AgentIdentifier | None = None
    acl_representation: str = STRING_REPRESENTATION
    payload_length: int | None = None
    payload_encoding: str | None = None
    date: str | None = None
    intended_receiver: tuple[AgentIdentifier, ...] = ()
    comments: str = ""

    @property
    def receivers(self) -> tuple[AgentIdentifier, ...]:
        """The agents this copy is delivered to: ``intended_receiver`` when given, else ``to``
        (FIPA SC00067 §4.3)."""
        return self.intended_receiver or self.to


def _aid_element(parent: ET.Element, tag: str, agent: AgentIdentifier) -> None:
    outer = ET.SubElement(parent, tag)
    aid = ET.SubElement(outer, "agent-identifier")
    ET.SubElement(aid, "name").text = agent.name
    addresses = ET.SubElement(aid, "addresses")
    for url in agent.addresses:
        ET.SubElement(addresses, "url").text = url


def _text(parent: ET.Element, tag: str, text: str) -> None:
    ET.SubElement(parent, tag).text = text


def to_xml(envelope: Envelope) -> bytes:
    """``envelope`` as the XML of FIPA SC00085, in the order JADE writes it (module docstring);
    UTF-8 octets beginning with ``<?xml version="1.0"?>``."""
    root = ET.Element("envelope")
    params = ET.SubElement(root, "params", {"index": "1"})
    for agent in envelope.to:
        _aid_element(params, "to", agent)
    if envelope.from_ is not None:
        _aid_element(params, "from", envelope.from_)
    if envelope.comments:
        _text(params, "comments", envelope.comments)
    _text(params, "acl-representation", envelope.acl_representation)
    if envelope.payload_length is not None:
        _text(params, "payload-length", str(envelope.payload_length))
    if envelope.payload_encoding:
        _text(params, "payload-encoding", envelope.payload_encoding)
    if envelope.date:
        _text(params, "date", envelope.date)
    for agent in envelope.intended_receiver:
        _aid_element(params, "intended-receiver", agent)
    return b'<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode").encode("utf-8")


def _local(tag: object) -> str:
    """An element's tag without namespace, lower case (JADE compares tags ignoring case)."""
    name = tag if isinstance(tag, str) else ""
    return name.rpartition("}")[2].lower()


def _child(element: ET.Element, tag: str) -> ET.Element | None:
    return next((c for c in element if _local(c.tag) == tag), None)


def _aid(outer: ET.Element, where: str) -> AgentIdentifier:
    inner = _child(outer, "agent-identifier")
    if inner is None:
        raise EnvelopeError(f"<{where}> holds no <agent-identifier>")
    name_el = _child(inner, "name")
    name = (name_el.text or "").strip() if name_el is not None else ""
    if not name:
        raise EnvelopeError(f"an <agent-identifier> in <{where}> has no <name>")
    try:
        return AgentIdentifier(name, _urls(inner))
    except ValueError as exc:
        raise EnvelopeError(f"<{where}>: {exc}") from None


def _urls(inner: ET.Element) -> tuple[str, ...]:
    """The non-empty ``<url>``s of an ``<agent-identifier>``'s ``<addresses>`` (none without)."""
    addresses = _child(inner, "addresses")
    if addresses is None:
        return ()
    return tuple(
        (u.text or "").strip() for u in addresses if _local(u.tag) == "url" and (u.text or "").strip()
    )


def parse_xml(data: bytes | str, *, max_size: int = MAX_ENVELOPE, max_digits: int = MAX_DIGITS) -> Envelope:
    """Read an XML envelope (FIPA SC00085; module docstring): at most ``max_size`` octets (or
    characters), no DTD, numbers of at most ``max_digits`` digits. Raises EnvelopeError."""
    root = _envelope_root(data, max_size)
    blocks = [p for p in root if _local(p.tag) == "params"]
    if not blocks:
        raise EnvelopeError("the envelope has no <params>")

    def index(p: ET.Element) -> int:
        return _number(p.get("index", "1"), "<params index>", max_digits)

    envelope = Envelope(to=(), acl_representation="")
    for block in sorted(blocks, key=index):
        envelope = _apply(envelope, block, max_digits)
    if not envelope.to:
        raise EnvelopeError("the envelope names no receiver (<to>)")
    if not envelope.acl_representation:
        raise EnvelopeError("the envelope gives no <acl-representation>")
    return envelope


def _envelope_root(data: bytes | str, max_size: int) -> ET.Element:
    """The ``<envelope>`` element of at most ``max_size`` octets (or characters) of XML without
    a DTD. Raises EnvelopeError."""
    if len(data) > max_size:
        raise EnvelopeError(f"the envelope is {len(data)} long (at most {max_size})")
    try:
        root = SafeET.fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except ET.ParseError as exc:
        raise EnvelopeError(f"the envelope is not XML: {exc}") from None
    except defusedxml.DefusedXmlException as exc:
        raise EnvelopeError(f"the envelope declares a DTD or entities, which are not read ({exc})") from None
    if _local(root.tag) != "envelope":
        raise EnvelopeError(f"the XML is a <{_local(root.tag)[:40]}>, not an <envelope>")
    return root


def _number(text: str, what: str, max_digits: int) -> int:
    """``text`` as a number of at most ``max_digits`` decimal digits, else EnvelopeError."""
    try:
        return read_digits(text, what, max_digits)
    except BoundError as exc:
        raise EnvelopeError(str(exc)) from None


def _apply(envelope: Envelope, block: ET.Element, max_digits: int) -> Envelope:
    """``envelope`` with the parameters of one ``params`` block replacing its own."""
    to = [_aid(e, "to") for e in block if _local(e.tag) == "to"]
    intended = [_aid(e, "intended-receiver") for e in block if _local(e.tag) == "intended-receiver"]
    changes: dict[str, object] = {}
    if to:
        changes["to"] = tuple(to)
    if intended:
        changes["intended_receiver"] = tuple(intended)
    for element in block:
        param = _PARAMS.get(_local(element.tag))
        if param is not None:
            field, read = param
            changes[field] = read(element, (element.text or "").strip(), max_digits)
    return replace(envelope, **changes)  # type: ignore[arg-type]


_PARAMS: dict[str, tuple[str, Callable[[ET.Element, str, int], object]]] = {
    "from": ("from_", lambda element, _text, _digits: _aid(element, "from")),
    "acl-representation": ("acl_representation", lambda _element, text, _digits: text),
    "payload-encoding": ("payload_encoding", lambda _element, text, _digits: text),
    "date": ("date", lambda _element, text, _digits: text),
    "comments": ("comments", lambda element, _text, _digits: element.text or ""),
    "payload-length": ("payload_length", lambda _e, text, digits: _number(text, "<payload-length>", digits)),
}
"""The single parameters of a ``params`` block: its tag → the Envelope field and how the field
is read from the element, its stripped text and the digits allowed (a later one replaces an
earlier one)."""
