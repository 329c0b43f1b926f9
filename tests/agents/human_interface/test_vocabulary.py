"""a_hi's vocabulary is the knowledge base's: built from a_km's answer to the vocabulary query,
so that a thing stated in the knowledge base a moment ago can be named in the next sentence."""

from __future__ import annotations

import pytest

from services.agents.human_interface.language import Command, UnknownReference, interpret
from services.agents.human_interface.vocabulary import (
    KNOWLEDGE_FILES,
    VARIABLES,
    VOCABULARY_QUERY,
    Vocabulary,
    words_of,
)
from services.agents.knowledge.world_model import WorldModel
from shared.fipa_codec.languages.l_hc import TaskAtom
from shared.fipa_codec.languages.l_wm import ObjectUpdate, SparqlQuery, WorldUpdate

pytestmark = pytest.mark.requirement("R1.3")


def test_a_km_answers_the_vocabulary_query_with_the_files_words() -> None:
    with WorldModel() as world:
        answer = world.answer(SparqlQuery(VOCABULARY_QUERY))
    assert answer.variables == VARIABLES
    assert Vocabulary.from_rows(answer.rows) == Vocabulary.from_files(KNOWLEDGE_FILES)


def test_labels_adjectives_places_and_content() -> None:
    v = Vocabulary.from_files(KNOWLEDGE_FILES)
    cup = v.thing("cup")
    assert cup is not None and ("mug",) in cup.nouns and ("coffee", "cup") in cup.nouns
    assert "small" in cup.adjectives and (cup.relation, cup.place) == ("in", "cabinet")
    beans = v.named(("beans",))
    assert [t.name for t in beans] == ["jar_content"] and beans[0].content and beans[0].place == "jar"
    assert {t.name for t in v.named(("container",))} == {"jar", "bowl", "cup", "cabinet"}
    assert all(t.name not in ("velma", "left_gripper", "head") for t in v.things), "robot parts are not named"
    assert words_of("Kitchen_Table") == ("kitchen", "table")


def test_a_thing_stated_at_run_time_can_be_named_at_once() -> None:
    with WorldModel() as world:
        before = Vocabulary.from_rows(world.answer(SparqlQuery(VOCABULARY_QUERY)).rows)
        with pytest.raises(UnknownReference, match="'tea'"):
            interpret("bring me the tea pot", vocabulary=before)
        # a_ta reports an object it has not seen before (no code change, no label: its name)
        world.apply(
            WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="tea_pot", location="table", relation="on"),))
        )
        after = Vocabulary.from_rows(world.answer(SparqlQuery(VOCABULARY_QUERY)).rows)
    assert interpret("bring me the tea pot", vocabulary=after) == Command(TaskAtom("bring", ("tea_pot",)))
    assert interpret("put the tea pot in the cabinet", vocabulary=after) == Command(
        TaskAtom("return", ("tea_pot",))
    )


def test_rows_it_does_not_understand_are_skipped() -> None:
    v = Vocabulary.from_rows(
        [(None, "label", "x"), ("https://w3id.org/roco/O_RoCo#cup", "label", None), ("a",)]
    )
    assert v.things == ()
