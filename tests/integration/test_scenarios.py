"""The library's scenarios with everything real: ``roco scenario NAME`` starts a router, the
recorder and one process per agent, ag_ex simulates Velma in MuJoCo, and the scenario's
expectations are checked; the run folder's report is read back (services/scenario/library).

Two runs also give ``roco replay`` the records it must reproduce besides a one-hop pour's:
``urgent_mid_pour`` runs with every communicate through the router (``--no-tls``: passwords
over TCP, no direct links), and ``two_commands`` with the traffic recorder killed for 2 s
during the pour (a fault step added to the library's scenario), so that a second incarnation
writes the rest, recovering what was sent meanwhile from the publishers' caches."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from services.report import build_report
from services.report.load import load_run
from services.runtime.run_folder import read_run_info
from services.scenario.model import LIBRARY
from services.spec_check.conformance import verify_report
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.machine import needs_camera
from tests.support.recorded_run import replay_lines
from tests.support.world import FULL, START, stands_at, untouched, world

pytestmark = [pytest.mark.slow, pytest.mark.fleet]

Run = tuple[subprocess.CompletedProcess[str], Path]
"""A scenario's ``roco scenario`` process (output, exit status) and its run folder."""


def scenario(name: str, runs: Path, *options: str) -> Run:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "scenario",
            name,
            "--runs-dir",
            str(runs),
            "--quiet",
            *options,
        ],
        capture_output=True,
        text=True,
        timeout=1500,
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    # self-collision is on: in no scenario does a command make the robot touch itself
    touched = [e.text for e in build_report(run_dir).events if e.kind == "self_contact"]
    assert touched == [], touched
    # and every scenario's record conforms to the specification (roco spec verify)
    conforms, text = verify_report(run_dir)
    assert conforms, f"{name}: {text[-4000:]}"
    return proc, run_dir


def sw_states(run_dir: Path) -> list[SWStatus]:
    return [
        m.content
        for m in load_run(run_dir).messages
        if m.channel == "C1" and m.sender == "a_ta" and isinstance(m.content, SWStatus)
    ]


RECORDER_KILLED = """
[[steps]]
fault = { service = "recorder", kind = "kill", down_s = 2.0 }
after = { step = "pregrasp", delay_s = 0.5 }
"""
"""A step added to ``two_commands``: the traffic recorder killed for 2 s half a second after
a_ta reports the pour's first pregrasp (services/scenario/model.py)."""


@pytest.fixture(scope="module")
def urgent_mid_pour(tmp_path_factory: pytest.TempPathFactory) -> Run:
    return scenario("urgent_mid_pour", tmp_path_factory.mktemp("runs"), "--no-tls")


@pytest.fixture(scope="module")
def two_commands(tmp_path_factory: pytest.TempPathFactory) -> Run:
    folder = tmp_path_factory.mktemp("scenario")
    killed = folder / "two_commands.toml"
    killed.write_text((LIBRARY / "two_commands.toml").read_text() + RECORDER_KILLED)
    return scenario(str(killed), tmp_path_factory.mktemp("runs"))


def test_an_urgent_command_preempts_the_pour_which_resumes(urgent_mid_pour: Run) -> None:
    proc, run_dir = urgent_mid_pour
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["succeeded", "succeeded"]
    texts = [e.text for e in report.coordination]
    cancel = next(i for i, t in enumerate(texts) if t.startswith("cancel"))
    terminating = next(i for i, t in enumerate(texts) if t.startswith("Terminating"))
    preempted = next(i for i, t in enumerate(texts) if t.startswith("Preempted"))
    assert cancel < terminating < preempted
    assert "put the jar down on the table" in texts[preempted]
    # the cup's plan ran between the preemption and the pour's end, and the pour finished
    assert re.search(r"^## \d+\. Commands and coordination", (run_dir / "report.md").read_text(), re.M)
    w = world(run_dir)
    assert stands_at(w["cup"], "table") and stands_at(w["bowl"], "table"), w
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]
    # cancel, Terminating, Preempted all within the coordinate protocol: scenario() verified it


def test_two_commands_in_a_row(two_commands: Run) -> None:
    proc, run_dir = two_commands
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["succeeded", "succeeded"]
    # the recorder killed during the pour: a second incarnation recovered what it missed
    checked = load_run(run_dir).integrity
    assert checked.intact and len(checked.incarnations) == 2 and checked.late > 0, checked.summary()
    w = world(run_dir)
    assert stands_at(w["cup"], "table") and stands_at(w["bowl"], "table"), w
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]
    # a lean fleet (tests/conftest.py): `roco scenario` took --no-record from ROCO_RERUN=0, and
    # its report drew no figures
    assert not (run_dir / "recording.rrd").exists() and not (run_dir / "rerun").exists()
    assert not (run_dir / "figures").exists()


@pytest.mark.requirement("R1.4")
def test_the_second_command_came_from_another_fipa_platform_through_the_gateway(two_commands: Run) -> None:
    """``two_commands``' pour is said by an agent of another FIPA platform (``from =
    "gateway"``): its fipa-request of a Sentence reached a_hi through the run's ACL gateway
    (C8) and was answered in its conversation with ``agree``, then the ``inform`` of a
    ``succeeded`` SentenceReport; ``roco spec trace`` on the run shows R1.4."""
    from services.gateway.platform import NAME
    from services.recorder.record import read_records
    from services.spec.model import DEFAULT_SPEC
    from services.spec_check.trace import Verdict, trace

    _, run_dir = two_commands
    c8 = [r for r in read_records(run_dir) if r.channel == "C8"]
    assert [(r.sender, r.receivers, r.performative) for r in c8] == [
        (NAME, ("a_hi",), "request"),
        ("a_hi", (NAME,), "agree"),
        ("a_hi", (NAME,), "inform"),
    ]
    traced = trace(DEFAULT_SPEC, [run_dir], tests=None)
    assert traced.leaves["R1.4"].verdict is Verdict.SHOWN, traced.leaves["R1.4"].runs


@needs_camera
@pytest.mark.parametrize("run", ["urgent_mid_pour", "two_commands"])
def test_the_head_camera_counts_most_spheres_in_the_bowl_after_the_pour(
    run: str, request: pytest.FixtureRequest
) -> None:
    """The content share of the last Observation of the bowl (services/report/content.py), the
    head camera's count: the pour, resumed after the preemption or followed by another
    command, left most spheres in the bowl."""
    _, run_dir = request.getfixturevalue(run)
    content = build_report(run_dir).content
    assert content.observed and content.share is not None and content.share >= 0.9, content


REPLAYED = ("a_co", "a_pl", "a_km", "a_ta")
"""The agents ``roco replay`` reproduces: those whose input is communicates only."""


def _inputs(run_dir: Path, agent: str) -> int:
    """The communicates to ``agent`` in the record, each once (a restarted recorder may have
    written one twice: the same publisher and sequence number)."""
    got = {
        (m.rec.source, m.rec.sn, m.rec.part) if m.rec.sn is not None else (None, m.rec.seq, 0)
        for m in load_run(run_dir).messages
        if m.rec.receivers[:1] == (agent,) and m.comm is not None
    }
    return len(got)


@pytest.mark.parametrize("run", ["urgent_mid_pour", "two_commands"])
def test_roco_replay_reproduces_each_agent_through_the_router_and_across_a_recorder_restart(
    run: str, request: pytest.FixtureRequest
) -> None:
    """``roco replay`` on the record made through the router (urgent_mid_pour: every agent's
    session says so) and on the one two recorder incarnations wrote (two_commands): each agent
    that takes only communicates reproduces what it sent, fed each recorded input once."""
    _, run_dir = request.getfixturevalue(run)
    if run == "urgent_mid_pour":
        for agent in (*REPLAYED, "a_hi"):
            assert ": router links (" in (run_dir / "logs" / f"{agent}.log").read_text(), agent
    lines = replay_lines(run_dir)
    for agent in REPLAYED:
        assert lines[agent].startswith(f"{agent}: reproduced, {_inputs(run_dir, agent)} inputs, "), lines


def _dropped(run_dir: Path, dest: Path, receiver: str) -> tuple[Path, str]:
    """A copy of ``run_dir``'s record without one communicate to ``receiver`` that its
    publisher sent more after (so the record shows it lost), and that communicate's sender."""
    from tests.support.recorded_run import copy_record, rewrite_record

    numbered = [(m, m.rec.source, m.rec.sn) for m in load_run(run_dir).messages]
    sent = Counter((source, sn) for _, source, sn in numbered)
    last: dict[str, int] = {}
    for _, source, sn in numbered:
        if source is not None and sn is not None:
            last[source] = max(sn, last.get(source, sn))
    gone = next(  # alone in its sample (not a batch), and its publisher sent more after it
        m
        for m, source, sn in numbered
        if m.rec.receivers[:1] == (receiver,)
        and source is not None
        and sn is not None
        and sn < last[source]
        and sent[(source, sn)] == 1
    )
    copy = rewrite_record(copy_record(run_dir, dest), lambda es: [e for e in es if e.ref != gone.rec.ref])
    return copy, gone.rec.sender


@pytest.mark.parametrize(("run", "receiver"), [("urgent_mid_pour", "a_pl"), ("two_commands", "a_km")])
def test_an_input_removed_from_the_record_is_said_missing_not_a_difference(
    run: str, receiver: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    """One communicate to ``receiver`` removed from a copy of the record: ``roco replay`` says
    in the receiver's line (and its sender's) that the record lacks it — and, for the record of
    a restarted recorder, when the recorder restarted — not what the replay then differs in;
    every other agent still reproduces."""
    from services.replay.driver import one_line, replay

    _, run_dir = request.getfixturevalue(run)
    copy, sender = _dropped(run_dir, tmp_path / "run", receiver)
    restarted = r" \(recorder restarted at \d+\.\d{3} s\)" if run == "two_commands" else ""
    line = one_line(replay(copy, receiver))
    assert re.fullmatch(f"{receiver}: cannot reproduce: 1 input missing from the record{restarted}", line), (
        line
    )
    if sender in REPLAYED:
        line = one_line(replay(copy, sender))
        assert re.fullmatch(
            f"{sender}: cannot reproduce: 1 output missing from the record{restarted}", line
        ), line
    for agent in set(REPLAYED) - {receiver, sender}:
        assert replay(copy, agent).equal, agent


@pytest.mark.parametrize("run", ["urgent_mid_pour", "two_commands"])
def test_a_cost_a_pl_draws_at_random_is_still_reported(
    run: str, request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Nondeterminism planted in a_pl — a random amount added to every plan's cost — is a
    difference in the content of each plan a_pl sent, and nowhere else, on these records too."""
    import random

    import services.agents.planner.agent as planner
    from services.recorder.record import read_records
    from services.replay.driver import render, replay

    to_hfsm = planner.to_hfsm

    def noisy(*args: object, **kwargs: object) -> tuple:
        root, complete, cost = to_hfsm(*args, **kwargs)  # type: ignore[arg-type]
        return root, complete, cost + random.uniform(0.5, 1.5)

    monkeypatch.setattr(planner, "to_hfsm", noisy)
    _, run_dir = request.getfixturevalue(run)
    result = replay(run_dir, "a_pl")
    plans = sorted(
        {r.seq for r in read_records(run_dir) if r.sender == "a_pl" and r.performative == "inform"}
    )
    assert plans and [(d.seq, d.field) for d in result.differences] == [(s, "content.cost") for s in plans], (
        render(result)
    )


def test_an_object_moved_after_it_was_seen_makes_a_ta_replan(tmp_path: Path) -> None:
    proc, run_dir = scenario("moved_object", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    reasons = [s.reason or "" for s in sw_states(run_dir) if s.state is SWState.REPLAN]
    assert any("jar is 4 cm from where the plan expects it" in r for r in reasons), reasons
    w = world(run_dir)
    assert stands_at(w["bowl"], "table") and (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


def test_impossible_commands_are_refused_with_a_reason(tmp_path: Path) -> None:
    proc, run_dir = scenario("impossible", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    # the teapot never becomes a command: a_hi names the word it does not know (the scenario
    # checks its answer), so only the pour into the cabinet reaches the report's commands
    assert [c.outcome for c in build_report(run_dir).commands] == ["failed"]
    w = world(run_dir)
    assert all(untouched(w[n]) for n in START), w  # nothing was moved


def test_a_km_restarted_between_commands_keeps_its_knowledge(tmp_path: Path) -> None:
    proc, run_dir = scenario("km_restart", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    log = (run_dir / "logs" / "a_km.log").read_text()
    assert "knowledge kept" in log
    info = read_run_info(run_dir)
    assert info.commands == ["bring the cup to the table", "bring the cup to the table"]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded", "failed"]
    w = world(run_dir)
    assert stands_at(w["cup"], "table") and untouched(w["jar"]) and untouched(w["bowl"]), w


def test_a_stop_mid_pour_puts_both_down_and_the_pour_asked_again_succeeds(tmp_path: Path) -> None:
    proc, run_dir = scenario("stop_mid_pour", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["stopped", "succeeded"]
    # the bowl first: the jar's turn and carry then pass clear of it (planner/clearance.py)
    put = "put the bowl down on the table and the jar down on the table"
    assert any(put in e.text for e in report.coordination), [e.text for e in report.coordination]
    # the second pour found the jar standing where the stop put it: no look missed it
    assert not any("was not seen" in e.text for e in report.coordination)
    w = world(run_dir)
    assert stands_at(w["bowl"], "table") and (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


def test_after_the_pour_jar_and_bowl_go_back_in_the_cabinet(tmp_path: Path) -> None:
    proc, run_dir = scenario("tidy_up", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded"] * 3
    w = world(run_dir)
    assert stands_at(w["jar"], "cabinet") and stands_at(w["bowl"], "cabinet"), w
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]


def test_a_pour_interrupted_twice_in_its_tilt_still_fills_the_bowl(tmp_path: Path) -> None:
    """a_ta killed half-way through the tilt, then ag_ex while the replanned pour brings the
    jar to its clear-view pose (scenario tilt_interrupted): each time a_ta reports Replan, the
    pour is replanned and finishes; the world shows the bowl on the table with the content in
    it."""
    proc, run_dir = scenario("tilt_interrupted", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert [c.outcome for c in build_report(run_dir).commands] == ["succeeded"]
    assert sum(s.state is SWState.REPLAN for s in sw_states(run_dir)) >= 2
    w = world(run_dir)
    assert stands_at(w["bowl"], "table") and (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]
    assert w["jar"].pose.position[2] > 0.5  # still in the hand or on furniture, not dropped


def test_a_placed_bowl_knocked_over_fails_the_task_with_the_reason(tmp_path: Path) -> None:
    proc, run_dir = scenario("knocked_bowl", tmp_path)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert [c.outcome for c in report.commands] == ["failed"]
    errors = [s.reason or "" for s in sw_states(run_dir) if s.state is SWState.ERROR]
    assert any("localise_bowl" in r and "the bowl is not upright: it leans 180°" in r for r in errors), errors
    bowl = world(run_dir)["bowl"]
    assert bowl.pose.tilt() > math.radians(170)  # still upside down where the person left it
