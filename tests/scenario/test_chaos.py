"""`roco chaos`: the faults it draws, the scenario steps that carry them, and the
verdict it reads from a traffic record (synthetic run folders here; a real chaos run is in
tests/integration/test_chaos.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from services.runtime.human import HumanReport, ReportKind
from services.runtime.run_folder import RunInfo, write_run_info
from services.scenario.chaos import SERVICE_ORDER, chaos_scenario, verdict, write_chaos_report
from services.scenario.model import ScenarioError, parse_scenario
from services.scenario.runner import CommandRecord, FaultRecord, ScenarioOutcome
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from tests.report.conftest import STARTED, RunBuilder, write_traffic
from tests.support.ledger import ran


def test_each_service_is_faulted_once_in_a_seeded_random_order() -> None:
    a, b, c = chaos_scenario(1), chaos_scenario(1), chaos_scenario(2)
    assert a == b and a != c
    faults = [s.fault for s in a.steps if s.fault is not None]
    assert sorted(f.service for f in faults) == sorted(SERVICE_ORDER)
    assert {f.kind for f in faults} <= {"kill", "pause", "restart"}
    assert all(0.5 <= f.down_s <= 4.0 for f in faults)
    assert a.steps[0].say == "pour the jar into the bowl" and a.steps[0].expect == "succeeded"
    assert all(s.after is not None and 3.0 <= (s.after.seconds or 0) <= 8.0 for s in a.steps[1:])
    many = chaos_scenario(5, count=12, services=("a_ta",), kinds=("kill",))
    assert [(s.fault.service, s.fault.kind) for s in many.steps if s.fault] == [("a_ta", "kill")] * 12


def test_unknown_services_and_kinds_are_refused() -> None:
    with pytest.raises(ValueError, match="cannot fault a_xx"):
        chaos_scenario(0, services=("a_xx",))
    with pytest.raises(ValueError, match="not explode"):
        chaos_scenario(0, kinds=("explode",))


def test_a_scenario_file_can_carry_faults_and_bad_ones_are_named() -> None:
    sc = parse_scenario(
        'name = "x"\n[[steps]]\nsay = "pour the jar into the bowl"\n'
        '[[steps]]\nfault = { service = "a_ta", kind = "kill", down_s = 1.5 }\nafter = { seconds = 4 }\n'
    )
    assert sc.steps[1].fault is not None and sc.steps[1].action == "fault"
    assert sc.steps[1].after is not None and sc.steps[1].after.seconds == 4
    with pytest.raises(ScenarioError, match="step 2: no service 'a_zz'"):
        parse_scenario(
            'name = "x"\n[[steps]]\nsay = "hi"\n[[steps]]\nfault = { service = "a_zz", kind = "kill" }\n'
        )
    with pytest.raises(ScenarioError, match="fault kind must be one of"):
        parse_scenario('name = "x"\n[[steps]]\nfault = { service = "a_ta", kind = "melt" }\n')


def _observation(z_jar: float) -> Observation:
    return Observation(
        stamp=1.0,
        objects=(
            ObjectObservation(name="jar", pose=Pose((0.3, -0.6, z_jar))),
            ObjectObservation(name="bowl", pose=Pose((0.3, -0.5, 0.77))),
            ObjectObservation(name="cup", pose=Pose((0.8, 0.1, 0.9))),
            ObjectObservation(name="table", pose=Pose((0.3, -0.65, 0.0))),  # furniture stands on the floor
        ),
    )


def _run(tmp_path: Path, builder: RunBuilder) -> Path:
    d = tmp_path / "run"
    (d / "logs").mkdir(parents=True)
    write_run_info(d, RunInfo(started=STARTED))
    write_traffic(d, builder)
    return d


def _done(ok: bool = True) -> ScenarioOutcome:
    record = CommandRecord(1, "pour the jar into the bowl", "r1")
    record.final = HumanReport(
        request_id="r1", kind=ReportKind.SUCCEEDED if ok else ReportKind.FAILED, text=""
    )
    fault = FaultRecord(5.0, "a_ta", "kill", 2.0, 10, 11, 3.2, during_command=True)
    return ScenarioOutcome([record], "", [fault])


def test_the_verdict_of_a_run_that_kept_everything(tmp_path: Path) -> None:
    b = RunBuilder()
    b.add(1, "C5", "a_ta", "ag_ex", "request", protocol="fipa-request", conversation="c1", reply_with="q1")
    b.add(
        2,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        CommandResult(command="grasp", ok=True),
        protocol="fipa-request",
        conversation="c1",
        in_reply_to="q1",
    )
    # the same answer again (sent from memory for a retransmitted request): not a second execution
    b.add(
        3,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        CommandResult(command="grasp", ok=True),
        protocol="fipa-request",
        conversation="c1",
        in_reply_to="q1",
    )
    b.add(
        4,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        _observation(0.76),
        protocol="fipa-request",
        conversation="c2",
        in_reply_to="q2",
    )
    run = _run(tmp_path, b)
    ran(run, ("c1", "grasp", 1.0, 2.0), ("c2", "observe", 3.0, 3.1))
    v = verdict(run, _done())
    assert v.ok and v.faults == 1 and v.faults_during_command == 1
    text = write_chaos_report(run, chaos_scenario(0), _done(), v).read_text()
    assert "| 5.0 | a_ta | kill | 2.0 | 10 → 11 | 3.2 | yes |" in text
    # no command's task in this record (tests/scenario/test_chaos_world.py has them)
    assert "| task done | yes a_hi's reports: done; the world: agrees: nothing to check (judged on " in text
    assert "| nothing executed twice | yes ag_ex's ledger: 2 command(s) started by 1 ag_ex" in text


def test_the_report_says_what_load_ran_beside_the_fleet(tmp_path: Path) -> None:
    run = _run(tmp_path, RunBuilder())
    v = verdict(run, _done())
    line = "load: 2 busy process(es) beside the fleet, 118.0 s of CPU over 60.0 s (1.97 cores)"
    text = write_chaos_report(run, chaos_scenario(0), _done(), v, line).read_text()
    assert f"\n\n{line}\n\n| t (s) |" in text
    assert "load:" not in write_chaos_report(run, chaos_scenario(0), _done(), v).read_text()


def test_a_second_execution_a_dropped_object_and_a_lost_command_are_found(tmp_path: Path) -> None:
    b = RunBuilder()
    b.add(
        2,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        CommandResult(command="tilt", ok=True),
        protocol="fipa-request",
        conversation="c1",
        in_reply_to="q1",
    )
    b.add(
        9,
        "C5",
        "ag_ex",
        "a_ta",
        "failure",
        CommandResult(command="tilt", ok=False, reason="timeout"),
        protocol="fipa-request",
        conversation="c1",
        in_reply_to="q1",
    )
    b.add(
        10,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        _observation(0.04),
        protocol="fipa-request",
        conversation="c2",
        in_reply_to="q2",
    )
    run = _run(tmp_path, b)
    lost = _done()
    lost.commands[0].final = None
    v = verdict(run, lost)
    assert not v.ok and not v.task_done and v.commands_lost == 1
    assert v.executed_twice == ["ag_ex: c1"] and v.dropped == {"jar": 0.04}
    text = write_chaos_report(run, chaos_scenario(0), lost, v).read_text()
    judged = "(judged on the last observations during the run)"
    assert f"| no object dropped | **no** jar at z = 0.04 m {judged} |" in text


def test_on_two_hosts_the_routers_and_the_link_are_faulted_too() -> None:
    sc = chaos_scenario(3, hosts=True)
    faults = [s.fault for s in sc.steps if s.fault is not None]
    every = (*SERVICE_ORDER, "router_brain", "router_robot", "link")
    assert sorted(f.service for f in faults) == sorted(every)
    cut = next(f for f in faults if f.service == "link")
    assert cut.kind == "cut" and 2.0 <= cut.down_s <= 6.0
    assert all(f.kind in {"kill", "pause", "restart"} for f in faults if f.service != "link")
    with pytest.raises(ValueError, match="cannot fault link"):
        chaos_scenario(0, services=("link",))  # one host has no link
    with pytest.raises(ValueError, match="cannot fault router"):
        chaos_scenario(0, services=("router",), hosts=True)  # two hosts have two routers


def test_the_report_of_a_run_on_two_hosts_names_the_host_of_each_fault_and_when_the_link_was_down(
    tmp_path: Path,
) -> None:
    run = _run(tmp_path, RunBuilder())
    events = [
        {"t": STARTED, "event": "shaping", "delay_ms": 20, "jitter_ms": 5, "loss_pct": 1, "how": "relay"},
        {"t": STARTED + 12.0, "event": "down", "seconds": None},
        {"t": STARTED + 15.5, "event": "up"},
    ]
    (run / "link.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))
    outcome = _done()
    outcome.started = STARTED
    outcome.faults = [
        FaultRecord(5.0, "ag_ex", "kill", 2.0, 10, 11, 3.2, during_command=True, host="robot"),
        FaultRecord(12.0, "link", "cut", 3.5, None, None, 3.5, during_command=True, host="brain ↔ robot"),
    ]
    text = write_chaos_report(run, chaos_scenario(0, hosts=True), outcome, verdict(run, outcome)).read_text()
    assert "| 5.0 | robot | ag_ex | kill | 2.0 | 10 → 11 | 3.2 | yes |" in text
    assert "| 12.0 | brain ↔ robot | link | cut | 3.5 | – | 3.5 | yes |" in text
    assert "20 ± 5 ms each way, 1 % loss" in text
    assert "- link down from t = 12.0 s to t = 15.5 s (3.5 s)" in text


def test_an_object_that_fell_after_its_last_observation_is_found_in_the_final_world(tmp_path: Path) -> None:
    """The world process writes the kitchen as it left it (velma/world/main.py
    ``FINAL_FILE``): it is what "no object dropped" judges, not the last observations; one
    that does not fit the scene is not used."""
    import numpy as np

    from velma.world.files import FINAL_FILE
    from velma.world.hardware import SimulatedVelma

    b = RunBuilder()
    b.add(1, "C5", "ag_ex", "a_ta", "inform", _observation(0.76), protocol="fipa-request", conversation="c")
    run = _run(tmp_path, b)
    ran(run, ("c", "observe", 1.0, 1.0))
    assert verdict(run, _done()).ok  # as last observed, the jar stands on the table
    sim = SimulatedVelma()
    scene = np.zeros(sim.scene_size)
    sim.scene(scene)
    jar = sim.model.body("jar")
    adr = 1 + int(sim.model.jnt_qposadr[jar.jntadr[0]])
    scene[adr : adr + 3] = (1.2, 0.4, 0.05)  # the jar lies on the floor
    (run / FINAL_FILE).write_bytes(scene.tobytes())
    v = verdict(run, _done())
    assert not v.ok and set(v.dropped) == {"jar"} and v.dropped["jar"] == pytest.approx(0.05, abs=1e-3)
    assert v.judged_on == "the final world (the world's final scene)"
    (run / FINAL_FILE).write_bytes(scene[:-3].tobytes())  # not this kitchen
    assert verdict(run, _done()).judged_on == "the last observations during the run"


def test_an_agent_that_raised_fails_the_verdict(tmp_path: Path) -> None:
    """The sixth question: a run whose every other answer holds, with a_ta's counters planted
    with two handler errors and a_km's exit by itself, does not keep everything."""
    b = RunBuilder()
    b.add(1, "C5", "ag_ex", "a_ta", "inform", _observation(0.76), protocol="fipa-request", conversation="c")
    run = _run(tmp_path, b)
    ran(run, ("c", "observe", 0.5, 0.9))
    assert verdict(run, _done()).ok
    outcome = _done()
    outcome.raised = {"a_ta": {"handler_errors": 2}}
    outcome.crashed = {"a_km": [70]}
    v = verdict(run, outcome)
    assert not v.ok and v.task_done
    text = write_chaos_report(run, chaos_scenario(0), outcome, v).read_text()
    assert (
        "| no agent raised | **no** 2 handler errors in a_ta: see logs/a_ta.log; "
        "a_km exited (code 70) and was started again: see logs/a_km.log |"
    ) in text
