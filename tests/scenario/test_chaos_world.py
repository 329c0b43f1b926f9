"""`roco chaos`'s "task done" asks the world too, and each of its six questions says no to a
fault planted in a run that otherwise kept everything: a synthetic run folder (the traffic
record of a pour, ag_ex's ledger) with a planted final scene of the world
(tests/support/final_scene.py) — the simulation's truth, which the robot's count in the
record may contradict."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest

from services.agents.planner.hfsm import PLACED_MAX_TILT, PLACED_TOLERANCE_M
from services.report.load import Message, load_run
from services.runtime.human import HumanReport, ReportKind
from services.runtime.run_folder import RunInfo, write_run_info
from services.scenario.chaos import (
    LAST_OBSERVED,
    QUESTIONS,
    Verdict,
    chaos_scenario,
    judge_world,
    planned_places,
    verdict,
    write_chaos_report,
)
from services.scenario.runner import CommandRecord, FaultRecord, ScenarioOutcome
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Arm, CommandResult, Release
from shared.fipa_codec.languages.l_hc import HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_hfsm import (
    Assert,
    Execute,
    ExpectedPosition,
    HierarchicalPlan,
    Perceive,
    PlanNode,
)
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.report.conftest import STARTED, RunBuilder, write_raw, write_traffic
from tests.support.final_scene import BOWL_PLACE, plant_final_scene
from tests.support.ledger import ran

POUR = TaskAtom("pour", ("jar", "bowl"))
ROOT = "pour(jar,bowl)"
PLACED = ExpectedPosition(
    object="bowl", position=BOWL_PLACE, tolerance=PLACED_TOLERANCE_M, max_tilt=PLACED_MAX_TILT
)
"""Where the plan puts the bowl, as its placement-judging look expects it (planner/hfsm.py)."""
FINAL_SCENE = "the final world (the world's final scene)"


def _leaf(name: str, action: Execute | Perceive | Assert) -> PlanNode:
    return PlanNode(name=name, action=action)


def _plan() -> HierarchicalPlan:
    """A pour's plan as a_pl makes it, cut to what the judges read: the bowl set down and
    looked at where it was put (the look judges the placement), the jar taken, put down in a
    safe place by the safe stop and taken again."""
    place_bowl = PlanNode(
        name="place_bowl",
        children=(
            _leaf("release", Execute(Release(arm=Arm.LEFT))),
            _leaf("put", Assert(subject="bowl", relation="on", object="table")),
            _leaf("perceive", Perceive(objects=("bowl",), expect=(PLACED,), judges=True)),
        ),
    )
    jar_seen = ExpectedPosition(object="jar", position=(0.7, 0.2, 0.85))  # a look before a grasp
    see_jar = _leaf("see_jar", Perceive(objects=("jar",), expect=(jar_seen,)))
    take_jar = _leaf("held", Assert(subject="jar", relation="heldBy", object="right_gripper"))
    jar_placed = ExpectedPosition(object="jar", position=(0.3, -0.7, 0.75), max_tilt=PLACED_MAX_TILT)
    stop = PlanNode(
        name="safe_stop_1",
        children=(_leaf("perceive", Perceive(objects=("jar",), expect=(jar_placed,), judges=True)),),
    )
    return HierarchicalPlan(
        plan_id="p1",
        task_id="cmd-1",
        root=PlanNode(
            name=ROOT, children=(place_bowl, PlanNode(name="fetch_jar", children=(see_jar, take_jar)))
        ),
        safe_stops={"safe_stop_1": stop},
    )


def _began(b: RunBuilder, t: float, step: str) -> None:
    """a_ta tells a_co it began the leaf ``step`` of plan p1."""
    status = SWStatus(state=SWState.RUNNING, plan_id="p1", step=step)
    b.add(t, "C1", "a_ta", "a_co", "inform", status, protocol="coordinate", conversation="plan-1")


def _robot_saw(in_bowl: int) -> Observation:
    """ag_ex's last Observation: the bowl where it was put, with ``in_bowl`` of 18 spheres."""
    return Observation(
        stamp=55.0,
        objects=(
            ObjectObservation(name="jar", pose=Pose((0.3, -0.6, 0.9))),
            ObjectObservation(name="bowl", pose=Pose(BOWL_PLACE), particles_inside=in_bowl),
            ObjectObservation(name="cup", pose=Pose((0.7, 0.0, 0.85))),
        ),
        total_particles=18,
    )


def _pour_record(*, robot_count: int = 18, twice: bool = False) -> RunBuilder:
    """The record of a pour: the person's command (C2), its plan (C1) with a_ta beginning the
    bowl's placement look, ag_ex's grasp answer and its last Observation (C5, counting
    ``robot_count`` spheres in the bowl), and last a_co's confirm (the record's last
    communicate, whose payload the record-intact fault takes away). ``twice``: ag_ex answers the
    grasp a second time, differently (a second execution)."""
    b = RunBuilder()
    command = HumanCommand(text="pour the jar into the bowl", goal=POUR)
    b.add(1.0, "C2", "a_hi", "a_co", "request", command, protocol="fipa-request", conversation="cmd-1")
    b.add(2.0, "C1", "a_co", "a_ta", "request", _plan(), protocol="coordinate", conversation="plan-1")
    _began(b, 3.0, f"{ROOT}/place_bowl/perceive")
    grasp = {"protocol": "fipa-request", "conversation": "c1", "in_reply_to": "q1"}
    b.add(4.0, "C5", "a_ta", "ag_ex", "request", protocol="fipa-request", conversation="c1", reply_with="q1")
    b.add(5.0, "C5", "ag_ex", "a_ta", "inform", CommandResult(command="grasp", ok=True), **grasp)
    if twice:
        b.add(
            5.5,
            "C5",
            "ag_ex",
            "a_ta",
            "failure",
            CommandResult(command="grasp", ok=False, reason="x"),
            **grasp,
        )
    saw = {"protocol": "fipa-request", "conversation": "c2", "in_reply_to": "q2"}
    b.add(6.0, "C5", "ag_ex", "a_ta", "inform", _robot_saw(robot_count), **saw)
    b.add(7.0, "C1", "a_co", "a_ta", "confirm", protocol="coordinate", conversation="plan-1")
    return b


def _run_folder(
    tmp_path: Path, b: RunBuilder, *, in_bowl: int | None = 18, **where: tuple[float, float, float]
) -> Path:
    """A run folder of ``b`` with ag_ex's ledger of its two commands and, unless ``in_bowl``
    is None, a final scene with ``in_bowl`` spheres in the bowl (``where``: the bowl's and
    the jar's positions)."""
    d = tmp_path / "run"
    (d / "logs").mkdir(parents=True)
    write_run_info(d, RunInfo(started=STARTED))
    write_traffic(d, b)
    ran(d, ("c1", "grasp", 1.0, 2.0), ("c2", "observe", 3.0, 3.1))
    if in_bowl is not None:
        plant_final_scene(d, in_bowl, **where)
    return d


def _outcome(kind: ReportKind = ReportKind.SUCCEEDED) -> ScenarioOutcome:
    """a_hi's final report of the pour, of ``kind``; one fault, during the command."""
    record = CommandRecord(1, "pour the jar into the bowl", "r1")
    record.final = HumanReport(request_id="r1", kind=kind, text="")
    return ScenarioOutcome(
        [record], "", [FaultRecord(5.0, "a_co", "kill", 2.0, 10, 11, 3.0, during_command=True)]
    )


def _answers(run: Path, outcome: ScenarioOutcome, v: Verdict) -> dict[str, str]:
    """chaos.md's answer to each question, by question."""
    text = write_chaos_report(run, chaos_scenario(0), outcome, v).read_text()
    table = text.split("| question | answer |\n|---|---|\n", 1)[1].split("\n\n", 1)[0]
    return {row.split(" | ")[0].strip("| "): row.split(" | ", 1)[1] for row in table.splitlines()}


def test_a_reported_success_with_spheres_missing_from_the_bowl_is_not_the_task_done(tmp_path: Path) -> None:
    """The robot counted 18 (its last Observation) and a_hi reported success, but the
    simulation holds 12 in the bowl: the world disagrees, and the report says it is the world."""
    run = _run_folder(tmp_path, _pour_record(robot_count=18), in_bowl=12)
    v = verdict(run, _outcome())
    assert v.reported_done and not v.world.agrees and not v.task_done and not v.ok
    assert v.world.found == ["the bowl holds 12 of 18 spheres, fewer than the 90 % a pour needs"]
    assert _answers(run, _outcome(), v)["task done"] == (
        "**no** a_hi's reports: done; the world: **disagrees**: the bowl holds 12 of 18 spheres, "
        f"fewer than the 90 % a pour needs (judged on {FINAL_SCENE}) |"
    )


def test_a_world_that_shows_the_task_done_does_not_make_a_failed_report_done(tmp_path: Path) -> None:
    run = _run_folder(tmp_path, _pour_record(), in_bowl=18)
    failed = _outcome(ReportKind.FAILED)
    v = verdict(run, failed)
    assert v.world.agrees and not v.reported_done and not v.task_done and not v.ok
    assert _answers(run, failed, v)["task done"] == (
        "**no** a_hi's reports: **not done**; the world: agrees: the bowl holds 18 of 18 spheres; "
        f"the bowl stands where the plan put it (judged on {FINAL_SCENE}) |"
    )


def test_a_reported_success_the_world_agrees_with_is_the_task_done(tmp_path: Path) -> None:
    run = _run_folder(tmp_path, _pour_record(), in_bowl=18)
    v = verdict(run, _outcome())
    assert v.task_done and v.ok and v.world.judged_on == FINAL_SCENE
    assert _answers(run, _outcome(), v)["task done"].startswith(
        "yes a_hi's reports: done; the world: agrees: "
    )


@pytest.mark.parametrize(("in_bowl", "agrees"), [(18, True), (17, True), (16, False), (0, False)])
def test_the_bowl_must_hold_the_share_a_pour_needs_by_the_simulation_s_count(
    tmp_path: Path, in_bowl: int, agrees: bool
) -> None:
    """90 % of 18 (services/agents/planner/domain.py ``CONTENT_SHARE_REQUIRED``): 17 is enough,
    16 is not, whatever the robot counted (18 here)."""
    run = _run_folder(tmp_path, _pour_record(robot_count=18), in_bowl=in_bowl)
    assert verdict(run, _outcome()).task_done is agrees


def test_a_bowl_not_where_the_plan_put_it_is_not_the_task_done(tmp_path: Path) -> None:
    """The bowl with all 18 spheres, 5 cm from where the plan set it down (a_ta's placement
    look allows 3 cm)."""
    x, y, z = BOWL_PLACE
    run = _run_folder(tmp_path, _pour_record(), in_bowl=18, bowl_at=(x + 0.05, y, z))
    v = verdict(run, _outcome())
    assert not v.task_done and v.world.found == ["the bowl stands 5.0 cm from where the plan put it"]
    assert v.world.held == ["the bowl holds 18 of 18 spheres"]


def _messages(tmp_path: Path, b: RunBuilder) -> list[Message]:
    """The record ``b`` as the judges read it."""
    d = tmp_path / f"record{len(b.records)}"
    d.mkdir()
    write_traffic(d, b)
    return load_run(d).messages


def test_the_places_are_those_of_the_placements_a_ta_began_and_an_object_taken_again_has_none(
    tmp_path: Path,
) -> None:
    """The bowl's placement look began: the bowl has its place; a look that does not judge a
    placement (before a grasp) gives none. The jar's placement look (in the safe stop) began
    too, but a leaf after it asserts the jar held again: it has none. A report of a plan not in
    the record changes nothing."""
    b = RunBuilder()
    b.add(1.0, "C1", "a_co", "a_ta", "request", _plan(), protocol="coordinate", conversation="plan-1")
    assert planned_places(_messages(tmp_path, b)) == {}  # nothing began
    _began(b, 1.5, f"{ROOT}/fetch_jar/see_jar")
    assert planned_places(_messages(tmp_path, b)) == {}
    _began(b, 2.0, f"{ROOT}/place_bowl/perceive")
    _began(b, 3.0, "safe_stop_1/perceive")
    both = planned_places(_messages(tmp_path, b))
    assert set(both) == {"bowl", "jar"} and both["bowl"] == PLACED
    _began(b, 4.0, f"{ROOT}/fetch_jar/held")
    status = SWStatus(state=SWState.RUNNING, plan_id="p9", step="safe_stop_1/perceive")  # no such plan
    b.add(5.0, "C1", "a_ta", "a_co", "inform", status, protocol="coordinate", conversation="plan-9")
    assert planned_places(_messages(tmp_path, b)) == {"bowl": PLACED}


def test_an_object_that_leans_or_is_not_in_the_world_is_not_where_the_plan_put_it() -> None:
    tilted = Pose(BOWL_PLACE, (math.cos(0.2), math.sin(0.2), 0.0, 0.0))  # 23° about x
    world = Observation(
        stamp=1.0,
        objects=(ObjectObservation(name="bowl", pose=tilted, particles_inside=18),),
        total_particles=18,
    )
    check = judge_world(world, [POUR], {"bowl": PLACED}, "w")
    assert check.found == ["the bowl leans 23°"] and check.held == ["the bowl holds 18 of 18 spheres"]
    nothing = judge_world(None, [POUR, TaskAtom("bring", ("cup",))], {"cup": PLACED}, "w")
    assert nothing.found == ["the bowl's content is not known", "the cup is not known (the plan put it down)"]
    assert judge_world(None, [TaskAtom("bring", ("cup",))], {}, "w").summary() == (
        "agrees: nothing to check (judged on w)"
    )


@pytest.mark.parametrize(("robot_count", "agrees"), [(18, True), (10, False)])
def test_without_a_final_scene_the_world_is_judged_as_last_observed_and_the_report_says_so(
    tmp_path: Path, robot_count: int, agrees: bool
) -> None:
    """ROCO_WORLD=loop leaves no final scene: the world is the objects as ag_ex last observed
    them, and the bowl's content its last count."""
    run = _run_folder(tmp_path, _pour_record(robot_count=robot_count), in_bowl=None)
    v = verdict(run, _outcome())
    assert v.world.judged_on == LAST_OBSERVED and v.world.agrees is agrees and v.task_done is agrees
    assert f"(judged on {LAST_OBSERVED}) |" in _answers(run, _outcome(), v)["task done"]


def _lose_last_payload(run: Path, b: RunBuilder, outcome: ScenarioOutcome) -> None:
    """The record keeps its last record without the payload (a_co's confirm)."""
    write_raw(run, [(r.seq, p) for r, p in zip(b.records[:-1], b.payloads[:-1], strict=True)])


Plant = Callable[[Path, RunBuilder, ScenarioOutcome], None]


def _report_failed(run: Path, b: RunBuilder, outcome: ScenarioOutcome) -> None:
    outcome.commands[0].final = HumanReport(request_id="r1", kind=ReportKind.FAILED, text="")


def _spheres_missing(run: Path, b: RunBuilder, outcome: ScenarioOutcome) -> None:
    plant_final_scene(run, 12)


def _command_lost(run: Path, b: RunBuilder, outcome: ScenarioOutcome) -> None:
    outcome.commands[0].final = None


def _jar_on_the_floor(run: Path, b: RunBuilder, outcome: ScenarioOutcome) -> None:
    plant_final_scene(run, 18, jar_at=(1.2, 0.4, 0.05))


def _agent_raised(run: Path, b: RunBuilder, outcome: ScenarioOutcome) -> None:
    outcome.raised = {"a_ta": {"handler_errors": 1}}


@pytest.mark.parametrize(
    ("plant", "twice", "no"),
    [
        (_report_failed, False, {"task done"}),
        (_spheres_missing, False, {"task done"}),
        (_command_lost, False, {"task done", "no command lost"}),
        (None, True, {"nothing executed twice"}),
        (_jar_on_the_floor, False, {"no object dropped"}),
        (_lose_last_payload, False, {"record intact"}),
        (_agent_raised, False, {"no agent raised"}),
    ],
    ids=["report failed", "spheres missing", "command lost", "executed twice", "dropped", "record", "raised"],
)
def test_each_question_says_no_to_its_own_planted_fault(
    tmp_path: Path, plant: Plant | None, twice: bool, no: set[str]
) -> None:
    """One fault planted in a run that otherwise kept everything: the questions it breaks say
    no, every other says yes, and the verdict fails."""
    b = _pour_record(twice=twice)
    run, outcome = _run_folder(tmp_path, b), _outcome()
    if plant is not None:
        plant(run, b, outcome)
    v = verdict(run, outcome)
    answers = _answers(run, outcome, v)
    assert {q for q in QUESTIONS if answers[q].startswith("**no**")} == no, answers
    assert {q for q in QUESTIONS if answers[q].startswith("yes")} == set(QUESTIONS) - no, answers
    assert not v.ok


def test_the_run_the_faults_are_planted_in_keeps_everything(tmp_path: Path) -> None:
    run = _run_folder(tmp_path, _pour_record())
    v = verdict(run, _outcome())
    assert v.ok and all(
        a.startswith("yes") for q, a in _answers(run, _outcome(), v).items() if q in QUESTIONS
    )


def test_an_object_ag_ex_never_observed_is_not_known_and_fails_no_object_dropped(tmp_path: Path) -> None:
    """Without a final scene (ROCO_WORLD=loop) the objects are judged as ag_ex last observed
    them: the cup it never observed is not known, and "no object dropped" says no."""
    saw = _robot_saw(18)
    no_cup = Observation(stamp=saw.stamp, objects=saw.objects[:2], total_particles=saw.total_particles)
    b = RunBuilder()
    answer = {"protocol": "fipa-request", "conversation": "c2", "in_reply_to": "q2"}
    b.add(6.0, "C5", "ag_ex", "a_ta", "inform", no_cup, **answer)
    run = _run_folder(tmp_path, b, in_bowl=None)
    v = verdict(run, _outcome())
    assert not v.last_observation and not v.dropped and not v.ok
    answers = _answers(run, _outcome(), v)
    assert {q for q in QUESTIONS if answers[q].startswith("**no**")} == {"no object dropped"}, answers
    dropped = f"**no** (not every object was observed) (judged on {LAST_OBSERVED}) |"
    assert answers["no object dropped"] == dropped
