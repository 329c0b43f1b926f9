"""A question back names what tells the things apart in the person's words (meaning.py
``_which``): where each is, else a describing word only it has, never an O_RoCo identifier
when a word does it."""

from __future__ import annotations

import pytest
from rdflib import Graph

from services.agents.human_interface.language import Ambiguous, interpret
from services.agents.human_interface.vocabulary import KNOWLEDGE_FILES, Vocabulary

PREFIX = "@prefix roco: <https://w3id.org/roco/O_RoCo#> .\n"


def _kitchen(extra: str) -> Vocabulary:
    graph = Graph()
    for path in KNOWLEDGE_FILES:
        graph.parse(path, format="turtle")
    graph.parse(data=PREFIX + extra, format="turtle")
    return Vocabulary.from_graph(graph)


def _asked(line: str, vocabulary: Vocabulary) -> str:
    with pytest.raises(Ambiguous) as info:
        interpret(line, vocabulary=vocabulary)
    return str(info.value)


def test_two_bowls_in_one_place_are_told_apart_by_their_words() -> None:
    v = _kitchen('roco:bowl_2 a roco:Bowl ; roco:in roco:cabinet ; roco:adjective "blue" , "ceramic" .')
    asked = _asked("bring me the bowl", v)
    assert asked == "Which bowl: the large bowl or the blue bowl?", asked
    assert "bowl 2" not in asked


def test_things_no_word_tells_apart_are_named() -> None:
    v = _kitchen(
        'roco:bowl_2 a roco:Bowl ; roco:in roco:cabinet ; roco:adjective "large", "white", "ceramic" .'
    )
    assert _asked("bring me the bowl", v) == "Which bowl: the bowl or the bowl 2?"


def test_one_said_of_things_of_several_kinds_names_each_by_its_kind() -> None:
    v = _kitchen('roco:bowl_2 a roco:Bowl ; roco:in roco:cabinet ; roco:adjective "blue" , "ceramic" .')
    asked = _asked("bring me the ceramic one", v)
    assert asked == "Which one: the large bowl, the blue bowl or the little cup?", asked


def test_a_vague_thing_is_asked_back_by_the_kinds_of_the_things() -> None:
    """ "that thing", "the thingy": a question back (not "I do not know 'thing'"), each thing
    named by its kind when no two are of one kind."""
    v = _kitchen("")
    assert (
        _asked("bring me that thing", v) == "Which one: the bowl, the cabinet, the cup, the jar or the table?"
    )
    assert _asked("bring me the thingy in the cabinet", v) == "Which one: the bowl, the cup or the jar?"
