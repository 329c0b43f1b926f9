"""a_km's knowledge base (services/agents/knowledge/world_model.py): persistence on Oxigraph,
hypothetical states (paper §5.7), stale observations, answers and their sizes."""

from __future__ import annotations

import logging
import signal
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest

from services.agents.knowledge.world_model import (
    ROCO,
    KnowledgeError,
    StoreError,
    UnsupportedQuery,
    WorldModel,
)
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import (
    HypotheticalQuery,
    ObjectQuery,
    ObjectUpdate,
    SceneQuery,
    SparqlQuery,
    WorldUpdate,
)

REPO = Path(__file__).resolve().parents[3]
JAR = (0.80, 0.22, 0.90)
BOWL = (0.80, -0.20, 0.90)


def observe(world: WorldModel, stamp: float, **positions: tuple[float, float, float]) -> None:
    world.apply(
        WorldUpdate(
            stamp=stamp, objects=tuple(ObjectUpdate(name=n, pose=Pose(p)) for n, p in positions.items())
        )
    )


def poses_of(world: WorldModel, name: str) -> list[str]:
    return [str(o) for o in world.graph.objects(ROCO[name], ROCO.hasPose)]


# ---- persistence -----------------------------------------------------------------------------


def test_an_empty_store_is_filled_with_the_ontology_and_the_kitchen(tmp_path: Path) -> None:
    with WorldModel(tmp_path / "km") as world:
        assert not world.kept
        assert world.object_info("jar").location == "cabinet"
        assert "table" in world.physical_objects()
        assert (tmp_path / "km").is_dir()


@pytest.mark.requirement("R2.4")
def test_knowledge_survives_a_new_world_model_on_the_same_store(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store = tmp_path / "km"
    with WorldModel(store) as first:
        observe(first, 2.0, jar=JAR)
        first.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="bowl", held_by="right_gripper"),)))
        first.apply(WorldUpdate(stamp=2.5, objects=(), total_particles=18))
        triples = len(first)
    with (
        caplog.at_level(logging.INFO, logger="services.agents.knowledge.world_model"),
        WorldModel(store) as second,
    ):
        assert second.kept
        assert len(second) == triples  # kept, not loaded a second time
        jar = second.object_info("jar")
        assert jar.pose == Pose(JAR) and jar.pose_stamp == 2.0 and jar.localised
        bowl = second.object_info("bowl")
        assert bowl.held_by == "right_gripper" and bowl.location is None and bowl.picked_from == "cabinet"
        assert second.total_particles == 18
        observe(second, 3.0, jar=BOWL)
    assert f"knowledge kept: {triples} triples" in caplog.text
    with WorldModel(store) as third:
        assert third.object_info("jar").pose == Pose(BOWL)


KILLED = """
import os, signal, sys
from pathlib import Path
from services.agents.knowledge.world_model import WorldModel
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
world = WorldModel(Path(sys.argv[1]))
world.apply(WorldUpdate(stamp=4.0, objects=(ObjectUpdate(name="jar", pose=Pose((0.1, 0.2, 0.3))),)))
world.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="bowl", location="table", relation="on"),)))
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_an_update_survives_kill_9_right_after_apply(tmp_path: Path) -> None:
    store = tmp_path / "km"
    done = subprocess.run(
        [sys.executable, "-c", KILLED, str(store)], cwd=REPO, capture_output=True, timeout=60, check=False
    )
    assert done.returncode == -signal.SIGKILL, done.stderr.decode()
    with WorldModel(store) as world:
        assert world.kept
        jar = world.object_info("jar")
        assert jar.pose == Pose((0.1, 0.2, 0.3)) and jar.pose_stamp == 4.0
        bowl = world.object_info("bowl")
        assert (bowl.location, bowl.relation) == ("table", "on")


def test_a_store_in_use_cannot_be_opened_twice(tmp_path: Path) -> None:
    with WorldModel(tmp_path / "km"), pytest.raises(StoreError, match="cannot open"):
        WorldModel(tmp_path / "km")


def test_in_memory_models_are_independent_and_a_closed_one_answers_nothing() -> None:
    a, b = WorldModel(), WorldModel()
    observe(a, 1.0, jar=JAR)
    assert a.object_info("jar").pose == Pose(JAR)
    assert b.object_info("jar").pose is None
    a.close()
    a.close()  # idempotent
    assert a.closed
    with pytest.raises(RuntimeError, match="closed"):
        a.answer(ObjectQuery("jar"))


# ---- hypothetical states (paper §5.7) ----------------------------------------------------


@pytest.mark.requirement("R2.3")
def test_hypothetical_grasp_answers_held_without_touching_the_real_state() -> None:
    world = WorldModel()
    observe(world, 1.0, jar=JAR)
    before = sorted(world.triples())
    answer = world.answer(
        HypotheticalQuery(
            changes=(ObjectUpdate(name="jar", held_by="left_gripper"),), query=ObjectQuery("jar")
        )
    )
    (jar,) = answer.objects
    assert jar.held_by == "left_gripper" and jar.location is None and jar.relation is None
    assert jar.picked_from == "cabinet" and not jar.localised
    assert sorted(world.triples()) == before
    real = world.object_info("jar")
    assert real.held_by is None and real.location == "cabinet"


@pytest.mark.requirement("R2.3")
def test_hypothetical_location_change_answers_a_sparql_ask() -> None:
    world = WorldModel()
    on_table = SparqlQuery("ASK { roco:jar roco:on roco:table }")
    changes = (
        ObjectUpdate(name="jar", held_by="left_gripper"),
        ObjectUpdate(name="jar", location="table", relation="on", held_by=""),
    )
    assert world.answer(HypotheticalQuery(changes=changes, query=on_table)).boolean is True
    assert world.answer(on_table).boolean is False
    assert world.answer(HypotheticalQuery(changes=changes[:1], query=on_table)).boolean is False


def test_hypothetical_pose_is_known_but_not_observed() -> None:
    world = WorldModel()
    observe(world, 1.0, bowl=BOWL)
    (bowl,) = world.answer(
        HypotheticalQuery(
            changes=(ObjectUpdate(name="bowl", pose=Pose((0.3, -0.4, 0.75))),), query=ObjectQuery("bowl")
        )
    ).objects
    assert bowl.pose == Pose((0.3, -0.4, 0.75)) and bowl.localised and bowl.pose_stamp is None
    assert world.object_info("bowl").pose == Pose(BOWL)


@pytest.mark.requirement("R2.3")
def test_a_hypothetical_scene_and_a_hypothetical_unknown_object() -> None:
    world = WorldModel()
    answer = world.answer(
        HypotheticalQuery(
            changes=(ObjectUpdate(name="teapot", location="table", relation="on"),), query=SceneQuery()
        )
    )
    teapot = next(o for o in answer.objects if o.name == "teapot")
    assert (teapot.type, teapot.location) == ("PhysicalObject", "table")
    with pytest.raises(KnowledgeError, match="teapot"):
        world.object_info("teapot")


# ---- stale observations ------------------------------------------------------------------


@pytest.mark.requirement("R2.4", "R3.2")
def test_a_newer_observation_supersedes_the_pose() -> None:
    world = WorldModel()
    observe(world, 1.0, jar=JAR)
    observe(world, 2.0, jar=BOWL)
    assert poses_of(world, "jar") == [str(ROCO.jar_pose)]
    pose_triples = list(world.graph.predicate_objects(ROCO.jar_pose))
    assert len(pose_triples) == 6  # type, position, orientation, frame, stamp, localised: one each
    jar = world.object_info("jar")
    assert jar.pose == Pose(BOWL) and jar.pose_stamp == 2.0
    assert world.stale_poses == 0


@pytest.mark.requirement("R2.4", "R3.2")
def test_an_older_observation_after_a_newer_one_is_ignored_for_the_pose() -> None:
    world = WorldModel()
    observe(world, 5.0, jar=JAR)
    world.apply(WorldUpdate(stamp=3.0, objects=(ObjectUpdate(name="jar", pose=Pose(BOWL), particles=7),)))
    jar = world.object_info("jar")
    assert jar.pose == Pose(JAR) and jar.pose_stamp == 5.0
    assert jar.particles == 7  # only the pose is superseded
    assert world.stale_poses == 1
    observe(world, 5.0, jar=BOWL)  # the same time is not older: taken
    assert world.object_info("jar").pose == Pose(BOWL) and world.stale_poses == 1


def test_an_asserted_change_carries_no_pose() -> None:
    world = WorldModel()
    observe(world, 5.0, jar=JAR)
    world.apply(
        WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", pose=Pose(BOWL), held_by="left_gripper"),))
    )
    jar = world.object_info("jar")
    assert jar.pose == Pose(JAR) and jar.held_by == "left_gripper" and not jar.localised
    assert world.unstamped_poses == 1


def test_changes_within_one_update_see_each_other_and_bad_ones_are_skipped() -> None:
    world = WorldModel()
    world.apply(
        WorldUpdate(
            stamp=-1.0,
            objects=(
                ObjectUpdate(name="bowl", held_by="right_gripper"),
                ObjectUpdate(name="bowl", location="table", relation="on", held_by=""),
                ObjectUpdate(name="jar", location="table", relation="under"),
                ObjectUpdate(name="bad name", held_by="left_gripper"),
            ),
        )
    )
    bowl = world.object_info("bowl")
    assert (bowl.location, bowl.relation, bowl.held_by) == ("table", "on", None)
    assert world.object_info("jar").location == "cabinet"
    assert world.rejected_changes == 2


# ---- queries -------------------------------------------------------------------------------


def test_unknown_or_malformed_queries_raise_knowledge_errors() -> None:
    world = WorldModel()
    with pytest.raises(KnowledgeError, match="teapot"):
        world.answer(ObjectQuery("teapot"))
    with pytest.raises(KnowledgeError, match="not an individual"):
        world.answer(ObjectQuery("jar> <x"))
    with pytest.raises(KnowledgeError, match="bad SPARQL"):
        world.answer(SparqlQuery("SELECT WHERE {"))
    before = len(world)
    with pytest.raises(KnowledgeError, match="bad SPARQL"):
        world.answer(SparqlQuery("INSERT DATA { roco:jar roco:on roco:table }"))
    assert len(world) == before
    with pytest.raises(UnsupportedQuery):
        world.answer(SparqlQuery("CONSTRUCT { ?s ?p ?o } WHERE { ?s ?p ?o }"))
    with pytest.raises(UnsupportedQuery, match="SERVICE"):
        world.answer(SparqlQuery("SELECT * WHERE { SERVICE <http://example.org/sparql> { ?s ?p ?o } }"))
    with pytest.raises(UnsupportedQuery):
        world.answer(
            HypotheticalQuery(changes=(), query=HypotheticalQuery(changes=(), query=SceneQuery()))  # type: ignore[arg-type]
        )


@pytest.mark.requirement("R2.3", "R2.4")
def test_sparql_select_rows_and_the_structured_answers() -> None:
    world = WorldModel()
    answer = world.answer(SparqlQuery("SELECT ?o ?nothing WHERE { ?o roco:in roco:cabinet } ORDER BY ?o"))
    assert answer.variables == ("o", "nothing")
    assert {(str(ROCO.bowl), None), (str(ROCO.jar), None)} <= set(answer.rows)
    objects = world.physical_objects()
    assert {"bowl", "cabinet", "jar", "jar_content", "table"} <= set(objects) and objects == sorted(objects)
    assert not {"left_gripper", "velma", "jar_pose"} & set(objects)
    grasps = world.grasps("jar", "left")
    assert [(g.name, g.on) for g in grasps] == [
        ("jar_side_grasp_left", ("cabinet",)),
        ("jar_side_grasp_left_from_above", ("table",)),
    ]
    assert world.grasps("jar", "right") == ()
    assert (0.31, -0.42, 0.75) in world.placement("bowl", "table").positions  # kitchen.ttl
    pour = world.pour("jar", "bowl")
    assert pour is not None and pour.angle == -2.3
    assert world.pour("bowl", "jar") is None


def test_answer_sizes_range_from_a_gripper_to_the_scene() -> None:
    world = WorldModel()
    world.apply(
        WorldUpdate(
            stamp=1.0,
            objects=(
                ObjectUpdate(name="jar", pose=Pose(JAR), particles=18),
                ObjectUpdate(name="bowl", pose=Pose(BOWL)),
            ),
            total_particles=18,
        )
    )
    gripper = len(msgspec.msgpack.encode(world.answer(ObjectQuery("left_gripper"))))
    jar = len(msgspec.msgpack.encode(world.answer(ObjectQuery("jar"))))
    scene = len(msgspec.msgpack.encode(world.answer(SceneQuery())))
    assert gripper < 500
    assert gripper < jar < scene


def test_a_pose_keeps_its_uncertainty_until_a_newer_observation_replaces_it() -> None:
    world = WorldModel()
    world.apply(
        WorldUpdate(stamp=1.0, objects=(ObjectUpdate(name="jar", pose=Pose(JAR), position_sigma=0.004),))
    )
    assert world.object_info("jar").position_sigma == 0.004
    world.apply(WorldUpdate(stamp=2.0, objects=(ObjectUpdate(name="jar", pose=Pose(JAR)),)))
    assert world.object_info("jar").position_sigma is None  # the newer observation gave none
    world.apply(
        WorldUpdate(stamp=3.0, objects=(ObjectUpdate(name="jar", pose=Pose(JAR), position_sigma=0.002),))
    )
    assert world.object_info("jar").position_sigma == 0.002


# ---- a power-cycled robot: the world taken anew ------------------------------------------------


def test_a_renewing_update_drops_what_was_believed_and_takes_the_initial_kitchen(tmp_path: Path) -> None:
    """After the robot's power cycle (its kitchen started anew, its time from 0) the update that
    renews the world replaces the beliefs of the old one: the jar back in the cabinet, not held,
    its content back in it, and the new observation's pose taken though its stamp is older."""
    with WorldModel(tmp_path / "km") as world:
        initial = world.object_info("jar")
        world.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", held_by="right_gripper"),)))
        world.apply(
            WorldUpdate(
                stamp=-1.0, objects=(ObjectUpdate(name="jar", location="table", relation="on", held_by=""),)
            )
        )
        observe(world, 268.2, jar=(0.6, -0.4, 0.8))
        world.apply(WorldUpdate(stamp=268.3, objects=(ObjectUpdate(name="bowl", particles=18),)))
        assert world.object_info("jar").location == "table"
        renewed = WorldUpdate(stamp=0.9, objects=(ObjectUpdate(name="jar", pose=Pose(JAR)),), renews=True)
        assert world.renew(renewed) == 1
        jar = world.object_info("jar")
        assert jar.location == initial.location == "cabinet" and not jar.held_by
        assert jar.pose == Pose(JAR) and jar.pose_stamp == 0.9
        assert world.object_info("bowl").particles == initial.particles
        assert world.stale_poses == 0
        # a later observation of the new world is taken as any other
        observe(world, 1.5, jar=BOWL)
        assert world.object_info("jar").pose_stamp == 1.5
    with WorldModel(tmp_path / "km") as kept:  # renewed on disk too
        assert kept.kept and kept.object_info("jar").location == "cabinet"
