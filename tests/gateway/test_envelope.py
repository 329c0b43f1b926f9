"""The XML envelope (FIPA SC00085) as JADE writes and reads it (services/gateway/envelope.py)."""

from __future__ import annotations

import pytest

from services.gateway.envelope import STRING_REPRESENTATION, Envelope, EnvelopeError, parse_xml, to_xml
from shared.fipa_codec import AgentIdentifier
from tests.support.jade_platform import JADE, envelope_xml


def test_what_jade_writes_reads_field_for_field() -> None:
    env = parse_xml(envelope_xml("a_hi", JADE, "http://host:7778/acc", 312))
    assert env.to == (AgentIdentifier("a_hi"),)
    assert env.from_ == AgentIdentifier(JADE, ("http://host:7778/acc",))
    assert env.acl_representation == STRING_REPRESENTATION
    assert env.payload_length == 312 and env.payload_encoding == "US-ASCII"
    assert env.date == "20261122T201900000Z"
    assert env.receivers == (AgentIdentifier("a_hi"),)


def test_written_and_read_back_unchanged_in_jades_order() -> None:
    env = Envelope(
        to=(AgentIdentifier(JADE, ("http://h:1/acc",)),),
        from_=AgentIdentifier("a_hi", ("http://127.0.0.1:7778/acc",)),
        payload_length=10,
        payload_encoding="UTF-8",
        date="20261122T201900000Z",
        comments="a & b < c",
    )
    xml = to_xml(env)
    assert xml.startswith(b'<?xml version="1.0"?>\n<envelope><params index="1"><to><agent-identifier>')
    order = [
        b"<to>",
        b"<from>",
        b"<comments>",
        b"<acl-representation>",
        b"<payload-length>",
        b"<payload-encoding>",
        b"<date>",
    ]
    assert [xml.index(t) for t in order] == sorted(xml.index(t) for t in order)
    assert parse_xml(xml) == env


def test_a_later_params_block_replaces_the_earlier_ones_fields() -> None:
    xml = (
        '<envelope><params index="2"><to><agent-identifier><name>a_hi</name></agent-identifier></to>'
        "<payload-length>5</payload-length></params>"
        '<params index="1"><to><agent-identifier><name>a_co</name></agent-identifier></to>'
        "<acl-representation>fipa.acl.rep.string.std</acl-representation>"
        "<payload-length>4</payload-length></params></envelope>"
    )
    env = parse_xml(xml)
    assert env.to == (AgentIdentifier("a_hi"),) and env.payload_length == 5
    assert env.acl_representation == STRING_REPRESENTATION


@pytest.mark.parametrize(
    ("xml", "message"),
    [
        ("<envelope><params>", "not XML"),
        ("<html/>", "not an <envelope>"),
        ("<envelope/>", "no <params>"),
        ('<envelope><params index="1"></params></envelope>', "no receiver"),
        ("<envelope><params><to><agent-identifier/></to></params></envelope>", "has no <name>"),
        (
            "<envelope><params><to><agent-identifier><name>(x)</name></agent-identifier></to></params></envelope>",
            "not a FIPA SC00070 word",
        ),
        (
            "<envelope><params><to><agent-identifier><name>a</name></agent-identifier></to>"
            "<payload-length>ten</payload-length></params></envelope>",
            "not a number",
        ),
    ],
)
def test_what_is_not_an_envelope_is_one_clear_error(xml: str, message: str) -> None:
    with pytest.raises(EnvelopeError, match=message):
        parse_xml(xml)


@pytest.mark.parametrize(
    ("xml", "message"),
    [
        ('<!DOCTYPE envelope [<!ENTITY a "b">]><envelope>&a;</envelope>', "declares a DTD or entities"),
        ('<!DOCTYPE envelope SYSTEM "http://evil/e.dtd"><envelope/>', "declares a DTD or entities"),
        (
            "<envelope><params><to><agent-identifier><name>a</name></agent-identifier></to>"
            f"<payload-length>{'9' * 5000}</payload-length></params></envelope>",
            "has 5000 digits",
        ),
        (f'<envelope><params index="{"1" * 13}"/></envelope>', "has 13 digits"),
        ("<envelope>" + " " * 70_000 + "</envelope>", "at most 65536"),
    ],
)
def test_dtds_long_numbers_and_large_envelopes_are_refused_before_they_are_read(
    xml: str, message: str
) -> None:
    with pytest.raises(EnvelopeError, match=message):
        parse_xml(xml)
