"""Agent names as FIPA SC00070 words, and their reversible mapping to Zenoh key chunks."""

from __future__ import annotations

import pytest
import zenoh
from fipa_strategies import agent_names, fipa_words, roco_names
from hypothesis import given
from hypothesis import strategies as st

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.names import (
    MAX_NAME_LENGTH,
    check_agent_name,
    is_word,
    key_chunk,
    name_of_key_chunk,
)
from shared.fipa_codec.string_form import parse, to_string


@pytest.mark.parametrize(
    "word",
    [
        "a_co",
        "da0@host:1099/JADE",
        "ams@192.168.1.2:1099/JADE",
        "http://robolab:7778/acc",
        "żółw",
        ":x",
        "a#b",
        'say"',
        "a\\b",
        "+x",
        ".x",
        "x-1",
        "T",
        "é@x",
        "~",
        "*",
    ],
)
def test_words(word: str) -> None:
    assert is_word(word)
    assert check_agent_name(word) == word


@pytest.mark.parametrize(
    "text",
    [
        "",
        "a b",
        "a\tb",
        "a(b",
        "a)",
        "#a",
        "9x",
        "-a",
        "@host",
        '"a"',
        "1",
        "+1",
        "-1.5e3",
        ".5",
        "20261121T153000000Z",
        "+00000000T011500035",
        "a\x00",
        "a\x7f\x20",
        "\ud800x",
    ],
)
def test_not_words(text: str) -> None:
    assert not is_word(text)
    with pytest.raises(ValueError, match="not a FIPA SC00070 word"):
        check_agent_name(text)
    with pytest.raises(ValueError, match="invalid agent name"):
        AgentIdentifier(text)


def test_name_length_is_bounded() -> None:
    assert AgentIdentifier("a" * MAX_NAME_LENGTH).name == "a" * MAX_NAME_LENGTH
    with pytest.raises(ValueError, match=f"longer than {MAX_NAME_LENGTH}"):
        AgentIdentifier("a" * (MAX_NAME_LENGTH + 1))


def test_addresses_are_words() -> None:
    assert (
        AgentIdentifier("a", ("http://h:7778/acc", "tcp/127.0.0.1:7447")).addresses[0] == "http://h:7778/acc"
    )
    for bad in ("tcp/x y", "(a)", "", "http://h/(x)"):
        with pytest.raises(ValueError, match="invalid address of agent a"):
            AgentIdentifier("a", (bad,))


@pytest.mark.parametrize(
    ("name", "chunk"),
    [
        ("a_co", "a_co"),
        ("ag_ex", "ag_ex"),
        ("da0@host:1099/JADE", "da0@host:1099%2FJADE"),
        ("a%b", "a%25b"),
        ("a*b$c?d#e", "a%2Ab%24c%3Fd%23e"),
        ("żółw", "%C5%BC%C3%B3%C5%82w"),
        ("~x", "%7Ex"),
    ],
)
def test_key_chunks(name: str, chunk: str) -> None:
    assert key_chunk(name) == chunk
    assert name_of_key_chunk(chunk) == name


@given(roco_names)
def test_roco_names_are_their_own_chunks(name: str) -> None:
    assert key_chunk(name) == name


@given(agent_names | fipa_words)
def test_every_name_has_one_chunk_and_back(name: str) -> None:
    chunk = key_chunk(name)
    assert name_of_key_chunk(chunk) == name
    key = f"roco/fipa/C1/{chunk}/a_co"
    assert str(zenoh.KeyExpr(key)) == key  # a canonical Zenoh key: one chunk, no wildcard
    assert not chunk.startswith("@")  # no verbatim chunk


@given(st.text(max_size=20))
def test_chunks_read_back_only_as_written(chunk: str) -> None:
    """name_of_key_chunk accepts exactly what key_chunk writes: no two chunks carry one name."""
    try:
        name = name_of_key_chunk(chunk)
    except ValueError:
        return
    assert key_chunk(name) == chunk


@pytest.mark.parametrize(
    "chunk",
    ["", "a/b", "a b", "a%2fb", "%61", "a%2", "%FF", "9x", "%40host", "a*", "%2Dx", "(x)"],
)
def test_chunks_that_carry_no_name(chunk: str) -> None:
    with pytest.raises(ValueError):
        name_of_key_chunk(chunk)


def test_names_that_have_no_chunk() -> None:
    for name in ("a b", "9x", "", "a" * (MAX_NAME_LENGTH + 1)):
        with pytest.raises(ValueError, match="invalid agent name"):
            key_chunk(name)


def test_jade_default_names_are_read_and_written() -> None:
    """JADE's default naming (local@host:port/JADE) in the string form, both ways."""
    text = (
        "(REQUEST :sender (agent-identifier :name da0@robolab:1099/JADE"
        " :addresses (sequence http://robolab:7778/acc))"
        ' :receiver (set (agent-identifier :name a_hi)) :content "pour" :protocol fipa-request)'
    )
    msg = parse(text)
    assert msg.sender == AgentIdentifier("da0@robolab:1099/JADE", ("http://robolab:7778/acc",))
    assert "(agent-identifier :name da0@robolab:1099/JADE :addresses (sequence http://robolab:7778/acc))" in (
        to_string(msg)
    )
    assert parse(to_string(msg)) == msg
    assert msg == Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("da0@robolab:1099/JADE", ("http://robolab:7778/acc",)),
        receiver=(AgentIdentifier("a_hi"),),
        content=b"pour",
        protocol="fipa-request",
    )


def test_names_and_words_found_valid_are_kept_and_invalid_ones_never_are(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from shared.fipa_codec import names

    monkeypatch.setattr(names, "KNOWN_NAMES", set())
    monkeypatch.setattr(names, "KNOWN_WORDS", set())
    assert check_agent_name("a_co") == "a_co" and "a_co" in names.KNOWN_NAMES
    assert is_word("fipa-request") and "fipa-request" in names.KNOWN_WORDS
    for bad in ("+1", "1x", "a b"):
        for _ in range(2):  # refused the second time as the first
            with pytest.raises(ValueError):
                check_agent_name(bad)
        assert bad not in names.KNOWN_NAMES and bad not in names.KNOWN_WORDS
    assert not is_word("+1") and not is_word("+1")
    # a long valid word is a word, and still no agent name once kept as a word
    long_word = "x" * (MAX_NAME_LENGTH + 1)
    assert is_word(long_word) and long_word in names.KNOWN_WORDS
    for _ in range(2):
        with pytest.raises(ValueError, match="longer than"):
            check_agent_name(long_word)
    assert long_word not in names.KNOWN_NAMES
    monkeypatch.setattr(names, "KNOWN_MAX", 0)
    check_agent_name("a_ta")
    assert "a_ta" not in names.KNOWN_NAMES  # the set is full: checked, not kept
