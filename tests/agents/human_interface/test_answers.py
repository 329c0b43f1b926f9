"""a_hi's answers to questions about the kitchen (answers.py): each question's SPARQL query run
by a_km's own knowledge base (services/agents/knowledge/world_model.py, in memory), and the one
sentence a_hi makes of its rows — saying when the knowledge is from, and what it does not know."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from services.agents.human_interface.answers import ROW_LIMIT, ago, answer_text, question_query
from services.agents.human_interface.intents import WorldQuestion
from services.agents.knowledge.world_model import WorldModel
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate

NOW = 1_800_000_000.0
"""a_hi's clock when it words the answers (POSIX s)."""
POSE = Pose(position=(0.3, -0.4, 0.75), orientation=(1.0, 0.0, 0.0, 0.0))


@pytest.fixture
def km() -> Iterator[WorldModel]:
    with WorldModel() as world:
        yield world


def say(km: WorldModel, q: WorldQuestion, now: float = NOW) -> str:
    return answer_text(q, km.sparql(question_query(q)).rows, now)


def look(km: WorldModel, seen_at: float, stamp: float = 5.0, **particles: int) -> None:
    """An observation as a_ta sends it: the named containers seen with their content count."""
    objects = tuple(ObjectUpdate(name=n, pose=POSE, particles=p) for n, p in particles.items())
    grip = ObjectUpdate(name="left_gripper", pose=POSE)
    km.apply(WorldUpdate(stamp=stamp, objects=(*objects, grip), seen_at=seen_at))


def test_before_a_look_a_hi_says_it_has_not_looked(km: WorldModel) -> None:
    assert say(km, WorldQuestion("contents", "bowl")) == "I have not looked into the bowl yet."
    assert say(km, WorldQuestion("empty", "jar")) == "I do not know: I have not looked into the jar yet."
    assert say(km, WorldQuestion("seen")) == "I have not looked at anything yet."
    assert say(km, WorldQuestion("where", "cup")) == "The cup is in the cabinet, as far as I know."


def test_what_a_ta_last_saw_is_told_with_its_age(km: WorldModel) -> None:
    look(km, NOW - 40, bowl=0, jar=60)
    assert say(km, WorldQuestion("contents", "bowl")) == (
        "The bowl held 0 spheres when I last looked, 40 s ago: it was empty."
    )
    assert say(km, WorldQuestion("empty", "bowl")) == "Yes, the bowl was empty when I last looked, 40 s ago."
    look(km, NOW - 12, stamp=30.0, bowl=18)
    held = "The bowl held 18 spheres when I last looked, 12 s ago."
    assert say(km, WorldQuestion("contents", "bowl")) == say(km, WorldQuestion("count", "bowl")) == held
    assert say(km, WorldQuestion("full", "bowl")) == (
        "No, the bowl held 18 of the 84 spheres it takes when I last looked, 12 s ago."
    )
    assert say(km, WorldQuestion("where", "bowl")) == "The bowl is in the cabinet; I last saw it 12 s ago."
    # the robot's own hand is no thing it saw
    assert say(km, WorldQuestion("seen")) == (
        "I have seen the bowl 12 s ago, 18 spheres in it; the jar 40 s ago, 60 spheres in it."
    )


def test_an_older_observation_does_not_make_the_sight_younger(km: WorldModel) -> None:
    look(km, NOW - 12, stamp=30.0, bowl=18)
    look(km, NOW - 5, stamp=20.0, bowl=17)  # a stale pose (observed before the one kept): ignored
    assert say(km, WorldQuestion("where", "bowl")) == "The bowl is in the cabinet; I last saw it 12 s ago."
    # the count is the last one a_ta sent (world_model.py: only the pose is superseded), with its age
    assert (
        say(km, WorldQuestion("contents", "bowl")) == "The bowl held 17 spheres when I last looked, 5 s ago."
    )


def test_a_look_that_counts_nothing_does_not_make_the_count_younger(km: WorldModel) -> None:
    look(km, NOW - 30, bowl=18)
    km.apply(WorldUpdate(stamp=9.0, objects=(ObjectUpdate(name="bowl", pose=POSE),), seen_at=NOW - 3))
    assert (
        say(km, WorldQuestion("contents", "bowl")) == "The bowl held 18 spheres when I last looked, 30 s ago."
    )
    assert say(km, WorldQuestion("where", "bowl")) == "The bowl is in the cabinet; I last saw it 3 s ago."
    assert say(km, WorldQuestion("seen")) == "I have seen the bowl 3 s ago."


def test_places_things_in_and_on_them_and_the_hand(km: WorldModel) -> None:
    assert say(km, WorldQuestion("on", "table")) == "Nothing is on the table, as far as I know."
    assert say(km, WorldQuestion("contents", "cabinet")) == (
        "The bowl, the cup and the jar are in the cabinet, as far as I know."
    )
    km.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="bowl", location="table", relation="on"),)))
    km.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", held_by="left_gripper"),)))
    assert say(km, WorldQuestion("on", "table")) == "On the table: the bowl, as far as I know."
    assert say(km, WorldQuestion("count", "cabinet", counted="things")) == (
        "1 thing in the cabinet, as far as I know: the cup."
    )
    assert say(km, WorldQuestion("where", "jar")) == "The jar is in my left hand, as far as I know."
    assert say(km, WorldQuestion("located", "bowl", place="table", relation="on")) == (
        "Yes, the bowl is on the table, as far as I know."
    )
    assert say(km, WorldQuestion("located", "cup", place="table", relation="on")) == (
        "No, the cup is in the cabinet, as far as I know."
    )


def test_a_thing_learnt_at_run_time_with_no_place_is_said_to_be_unknown(km: WorldModel) -> None:
    km.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="tea_pot"),)))
    assert say(km, WorldQuestion("where", "tea_pot")) == "I do not know where the tea pot is."


def test_the_queries_are_bounded_and_fit_the_channel() -> None:
    """C7's query-ref carries at most 2000 bytes (services/spec/robot_companion.toml)."""
    for q in (WorldQuestion("contents", "bowl"), WorldQuestion("seen")):
        text = question_query(q)
        assert text.endswith(f"LIMIT {ROW_LIMIT}") and len(text.encode()) < 1500
    with pytest.raises(ValueError, match="asks a_km nothing"):
        question_query(WorldQuestion("abilities"))


def test_ages_in_words() -> None:
    assert [ago(s) for s in (0.2, 40.4, 150.0, 7200.0)] == ["just now", "40 s ago", "2 min ago", "2 h ago"]
