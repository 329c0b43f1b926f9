"""The main job, as a user runs it: ``roco scenario FILE --gateway PORT`` (:data:`SESSION`: the
command ``roco run "pour the jar into the bowl"`` gives, and the person's question "what is in
the bowl?" right after it and once it ended) starts a router, the recorder, one OS process per
agent and the ACL gateway, and the robot pours the jar into the bowl in MuJoCo (paper §5.7).
Faster than real time (the executor is not paced). While it pours, an agent of another FIPA
platform (tests/support/jade_platform.py) asks a_hi through the gateway what it is doing
(requirement R1.4, channel C8)."""

from __future__ import annotations

import json
import os
import queue
import re
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import pytest

from services.fleet.launcher import free_port
from services.recorder.record import read_records
from services.report import build_report
from services.report.load import load_run
from services.runtime.run_folder import read_run_info
from services.spec.model import default_spec
from services.spec_check.conformance import verify_run
from shared.fipa_codec import Performative
from tests.support import forbidden
from tests.support.jade_platform import JADE, JadePlatform, Received
from tests.support.machine import needs_camera
from tests.support.raised import assert_no_agent_raised
from tests.support.recorded_run import replay_lines
from tests.support.world import FULL, stands_at, untouched, world

pytestmark = [pytest.mark.slow, pytest.mark.fleet, pytest.mark.as_users_run]

ASKED = "what are you doing?"
"""What the foreign agent asks a_hi while the robot pours."""
CONVERSATION = "status_jade"
"""The foreign agent's conversation-id (its reply-with: ``status_jade-r1``)."""
AGENTS = ("a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex")
"""Every agent of the fleet, each its own process."""
FINAL = {Performative.INFORM, Performative.FAILURE, Performative.REFUSE, Performative.NOT_UNDERSTOOD}
"""The answers that end a fipa-request (FIPA SC00026)."""
QUESTION = "what is in the bowl?"
SESSION = f"""name = "pour, and what is in the bowl before and after"
timeout_s = 900
[[steps]]
say = "pour the jar into the bowl"
[[steps]]
say = "{QUESTION}"
expect = "answer"
[[steps]]
say = "{QUESTION}"
after = {{ ended = 1 }}
expect = "answer"
"""
"""The session: the pour; the question right after it is said (a_km has a_ta's first look,
the pour has not begun), and again once the pour ended."""


@dataclass(frozen=True)
class PourRun:
    """The pour as ``roco run`` ran it (its output, exit status, run folder), and what the
    foreign agent received through the gateway while it ran (``foreign``, in order), or why it
    could not ask (``foreign_error``; "" when it asked and got a final answer)."""

    proc: subprocess.CompletedProcess[str]
    run_dir: Path
    foreign: tuple[Received, ...]
    foreign_error: str


class Lines:
    """The lines of a stream read on a thread of its own: all of them (:meth:`text`) and, as
    they come, the first that holds a text (:meth:`wait_for`)."""

    def __init__(self, stream: IO[str]) -> None:
        self.seen: list[str] = []
        self._new: queue.SimpleQueue[str | None] = queue.SimpleQueue()
        self._ended = False
        self.thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self.thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self.seen.append(line)
            self._new.put(line)
        self._new.put(None)

    def wait_for(self, text: str, deadline: float) -> str:
        """The next line holding ``text``; raises TimeoutError past ``deadline`` (monotonic s)
        or at the stream's end."""
        while not self._ended:
            try:
                line = self._new.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise TimeoutError(f"no line with {text!r} in time") from None
            if line is None:
                self._ended = True
            elif text in line:
                return line
        raise TimeoutError(f"the output ended before a line with {text!r}")

    def text(self) -> str:
        self.thread.join(timeout=60)
        return "".join(self.seen)


def ask_what_it_is_doing(jade: JadePlatform, port: int, out: Lines) -> tuple[list[Received], str]:
    """Once the gateway serves and a_co has the pour (it asked for plan #1), the foreign agent
    asks a_hi :data:`ASKED`; what it received until a final answer, and "" or why it stopped."""
    got: list[Received] = []
    url = f"http://127.0.0.1:{port}/acc"
    deadline = time.monotonic() + 600
    try:
        out.wait_for(f"gateway serving {url}", deadline)
        out.wait_for("plan #1 requested", deadline)
        sentence = json.dumps({"type": "sentence", "text": ASKED})
        status = jade.request(url, "a_hi", jade.acl("a_hi", sentence, CONVERSATION))
        if status != 200:
            return got, f"the gateway answered HTTP {status}"
        while not got or got[-1].msg.performative not in FINAL:
            got.append(jade.next(timeout=max(0.0, deadline - time.monotonic())))
    except (TimeoutError, queue.Empty, OSError) as exc:
        return got, f"{type(exc).__name__}: {exc}"
    return got, ""


@pytest.fixture(scope="module")
def pour_run(tmp_path_factory: pytest.TempPathFactory) -> PourRun:
    runs = tmp_path_factory.mktemp("runs")
    session = tmp_path_factory.mktemp("session") / "pour.toml"
    session.write_text(SESSION)
    port = free_port()
    jade = JadePlatform()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "services.cli",
            "scenario",
            str(session),
            "--runs-dir",
            str(runs),
            "--gateway",
            str(port),
        ],
        # the defaults a user gets: mutual TLS and access control (none of them set otherwise)
        env={k: v for k, v in os.environ.items() if k not in ("ROCO_TLS", "ROCO_ACL", "ROCO_SECURITY")},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None and proc.stderr is not None
    out, err = Lines(proc.stdout), Lines(proc.stderr)
    try:
        foreign, why = ask_what_it_is_doing(jade, port, out)
        proc.wait(timeout=1200)
    finally:
        jade.close()
        end(proc)
    done = subprocess.CompletedProcess(proc.args, proc.returncode, out.text(), err.text())
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return PourRun(done, run_dir, tuple(foreign), why)


def end(proc: subprocess.Popen[str]) -> None:
    """End ``roco run`` if it still runs: SIGTERM (it stops its fleet), SIGKILL after 60 s."""
    if proc.poll() is not None:
        return
    proc.terminate()
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@pytest.mark.requirement("R3.1")
def test_pour_succeeds_without_the_robot_touching_itself(pour_run: PourRun) -> None:
    proc, run_dir = pour_run.proc, pour_run.run_dir
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    report = build_report(run_dir)
    assert report.header.succeeded is True
    # self-collision is on: no command made the robot touch itself
    assert [e.text for e in report.events if e.kind == "self_contact"] == []


@needs_camera
@pytest.mark.requirement("R3.1")
def test_the_pour_ran_over_mutual_tls_with_access_control(pour_run: PourRun) -> None:
    """``roco run``'s default deployment (docs/security.md): the router listens on
    ``tls/127.0.0.1:PORT`` with access control, and every identity's certificate names it
    alone."""
    router_log = (pour_run.run_dir / "logs" / "router.stderr").read_text()
    assert "listening on tls/127.0.0.1:" in router_log and "access control from" in router_log
    acl = json.loads((pour_run.run_dir / "security" / "acl.json").read_text())
    assert acl["subjects"] and all(s["cert_common_names"] == [s["id"]] for s in acl["subjects"])


def test_the_head_camera_counts_most_spheres_in_the_bowl(pour_run: PourRun) -> None:
    """The content share of the last Observation of the bowl (services/report/content.py): the
    head camera's count, what a_ta judged the pour by."""
    content = build_report(pour_run.run_dir).content
    assert content.observed and content.share is not None
    assert content.share >= 0.9, content


@needs_camera
def test_the_report_says_how_many_spheres_were_seen_and_how_many_inferred(pour_run: PourRun) -> None:
    """The report's content section splits the count into the spheres the camera saw and those
    it inferred behind the bowl's wall, and names the look that decided; the outcome the person
    read says the same (services/agents/task_executor/verdict.py)."""
    c = build_report(pour_run.run_dir).content
    assert c.seen is not None and c.inferred is not None and c.seen + c.inferred == c.inside, c
    assert c.look in (1, 2)
    md = (pour_run.run_dir / "report.md").read_text(encoding="utf-8")
    section = md.split("Content outcome")[1]
    which = "second" if c.look == 2 else "first"
    split = f"{c.seen} seen and {c.inferred} inferred behind its wall" if c.inferred else "all seen"
    assert f"ended in the bowl: {split}" in section and f"at the {which} look" in section, section[:600]
    assert f"{c.inside} of {c.total} spheres" in pour_run.proc.stdout, pour_run.proc.stdout[-2000:]


@pytest.mark.requirement("R1.3")
def test_what_is_in_the_bowl_is_answered_from_a_km_before_and_after_the_pour(pour_run: PourRun) -> None:
    """The person's question, asked right after the pour was said and again once it ended, is
    answered from a_km (C7): no spheres first (a_ta's first look saw an empty bowl), then the
    count of a_ta's last look (the report's content section: the last Observation of the bowl),
    each saying how old the knowledge is."""
    outcomes = read_run_info(pour_run.run_dir).outcomes
    assert [(o.text, o.outcome) for o in outcomes] == [
        ("pour the jar into the bowl", "succeeded"),
        (QUESTION, "answer"),
        (QUESTION, "answer"),
    ], outcomes
    before, after = outcomes[1].detail, outcomes[2].detail
    assert re.fullmatch(
        r"The bowl held 0 spheres when I last looked, (just now|\d+ s ago): it was empty\.", before
    ), before
    inside = build_report(pour_run.run_dir).content.inside
    assert inside is not None and inside > 0
    assert re.fullmatch(
        rf"The bowl held {inside} spheres when I last looked, (just now|\d+ s ago)\.", after
    ), after
    records = read_records(pour_run.run_dir)
    asked = [
        r
        for r in records
        if r.channel == "C7" and r.sender == "a_hi" and (r.conversation_id or "").startswith("ask-")
    ]
    assert len(asked) == 2, asked


@pytest.mark.requirement("R3.1")
def test_the_bowl_stands_on_the_table_holding_the_content_in_the_simulated_world(pour_run: PourRun) -> None:
    """Judged by the world the run left (the world's final scene, the physics' truth), not by
    what the agents reported."""
    run_dir = pour_run.run_dir
    w = world(run_dir)
    assert stands_at(w["bowl"], "table"), w["bowl"]
    assert (w["bowl"].particles_inside or 0) >= FULL, w["bowl"]
    assert untouched(w["cup"]), w["cup"]


@needs_camera
def test_every_object_asked_for_was_seen_within_10_mm_the_held_jar_included(pour_run: PourRun) -> None:
    """The camera's observations beside the truth (ag_ex_perception.jsonl): the jar observed
    while the left hand holds it is localised at its height (segment.py ``lifted``), and no
    content was seen outside a container where there was none."""
    run_dir = pour_run.run_dir
    rows = build_report(run_dir).perception
    assert rows and all(r.seen for r in rows), [(r.object, r.reason) for r in rows if not r.seen]
    assert max(r.error_mm or 0.0 for r in rows) <= 10.0, [(r.object, r.sim_time, r.error_mm) for r in rows]
    assert any(r.object == "jar" and r.sim_time > 20.0 for r in rows)  # held, as a_ta checks the bowl
    # a sphere may spill in the pour (then the camera may miss it: it counts what it sees);
    # what it never does is see content outside where there is none
    assert all(
        r.outside <= r.outside_truth for r in rows if r.outside is not None and r.outside_truth is not None
    )


def test_no_agent_raised(pour_run: PourRun) -> None:
    """Every agent's handler_errors and behaviour_errors were 0 when the pour ended, and none
    exited by itself (services/runtime/raised.py): a pour that succeeded with handlers raising
    fails here."""
    assert_no_agent_raised(pour_run.run_dir, AGENTS)


def test_each_agent_ran_as_its_own_process(pour_run: PourRun) -> None:
    run_dir = pour_run.run_dir
    info = read_run_info(run_dir)
    assert set(AGENTS) <= set(info.processes)
    assert len({info.processes[a] for a in AGENTS}) == len(AGENTS)


def test_traffic_shows_both_planning_phases_and_all_six_participants(pour_run: PourRun) -> None:
    run_dir = pour_run.run_dir
    records = read_records(run_dir)
    senders = {r.sender for r in records}
    assert senders >= {"a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex"}
    assert {r.channel for r in records} == {"C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8"}
    report = build_report(run_dir)
    assert [p.outcome for p in report.plans][-2:] == ["partial", "complete"]
    md = (run_dir / "report.md").read_text()
    assert "Table 8" in md and "Table 7" in md


def test_progress_was_printed_as_it_happened(pour_run: PourRun) -> None:
    out = pour_run.proc.stdout
    assert "plan #1 requested" in out and "plan #2 requested" in out
    assert "Replan" in out and "Succeeded" in out
    # seconds apart, so in this order whatever the router's interleaving of two senders (a_co's
    # plan #2 request follows a_ta's Replan by milliseconds and may be printed first)
    assert out.index("plan #1 requested") < out.index("Replan") < out.index("Succeeded")
    assert out.index("plan #1 requested") < out.index("plan #2 requested")


@pytest.mark.requirement("R1.4")
def test_a_foreign_agent_asked_through_the_gateway_while_the_robot_poured(pour_run: PourRun) -> None:
    """The JADE-like agent's request (C8, fipa-request) reached a_hi through the gateway of the
    run and was answered at once with an ``inform`` of a_hi's status report, in the foreign
    agent's conversation, naming the pour under way (a status needs no ``agree``: it is done as
    soon as it is answered); it is recorded under the foreign agent's name, and the run's end
    says what crossed the gateway."""
    assert pour_run.foreign_error == "", (pour_run.foreign_error, pour_run.foreign)
    answers = [r.msg for r in pour_run.foreign]
    assert [m.performative for m in answers] == [Performative.INFORM], answers
    inform = answers[0]
    assert (inform.conversation_id, inform.in_reply_to) == (CONVERSATION, f"{CONVERSATION}-r1")
    assert inform.sender is not None and inform.sender.name == "a_hi"
    assert [r.name for r in inform.receiver] == [JADE]
    report = json.loads(inform.content)
    assert report["type"] == "sentence_report" and report["kind"] == "status", report
    assert "pour the jar into the bowl" in report["text"], report
    records = read_records(pour_run.run_dir)
    c8 = [(r.sender, r.receivers, r.performative) for r in records if r.channel == "C8"]
    assert c8 == [(JADE, ("a_hi",), "request"), ("a_hi", (JADE,), "inform")]
    assert "gateway: received 1, forwarded 1, refused 0, answered 1, posted 1" in pour_run.proc.stdout


def test_roco_spec_verify_reports_full_conformance_of_the_pour(pour_run: PourRun) -> None:
    run_dir = pour_run.run_dir
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "spec", "verify", str(run_dir)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "violations: none" in proc.stdout and "full conformance: yes" in proc.stdout


def test_the_run_leaves_one_rerun_recording_of_traffic_robot_and_scene(pour_run: PourRun) -> None:
    """Traffic (recorder), robot, scene and loop timing (ag_ex), the command queue (a_co):
    three parts merged into one recording."""
    from services.recorder.record import read_records
    from tests.viewer.test_recording import rows

    run_dir = pour_run.run_dir
    recording = run_dir / "recording.rrd"
    assert recording.exists(), sorted(p.name for p in run_dir.iterdir())
    counts = rows(recording)
    assert counts["/traffic/log"] == len(read_records(run_dir))  # one log line per communicate
    assert counts["/world/robot/grip/left"] > 100 and counts["/world/objects/jar"] > 0
    # the loop's timing at ≈ 1 Hz (ag_ex), a_co's queue
    assert counts["/robot/timing/compute/p99"] >= 10 and counts["/robot/timing/overruns/count"] >= 10
    assert counts["/task/queue"] >= 2 and counts["/task/queue/length"] == counts["/task/queue"]
    parts = sorted(p.name.split("-")[0] for p in (run_dir / "rerun").glob("*.rrd"))
    assert parts == ["a_co", "ag_ex", "recorder"]


@needs_camera
def test_the_recording_holds_the_head_camera_at_most_once_a_second(pour_run: PourRun) -> None:
    """ag_ex renders the head camera for the recording at most 1 Hz, at the lowest CPU priority:
    a tick that finds the CPUs busy is skipped (services/viewer/camera.py)."""
    from tests.viewer.test_recording import rows

    run_dir = pour_run.run_dir
    frames = rows(run_dir / "recording.rrd")["/world/robot/head_camera"]
    info = read_run_info(run_dir)
    assert info.ended is not None
    assert 3 <= frames <= info.ended - info.started + 1, (frames, info.ended - info.started)


def test_roco_spec_trace_shows_every_leaf_from_the_pour(pour_run: PourRun) -> None:
    """The pour, with the foreign agent's question through the gateway (R1.4), shows every leaf
    requirement but the three a single uninterrupted command cannot exercise (R1.2: a decision
    between two open commands; R2.1: an interruption for a waiting one; R3.3: a safe stop before
    Preempted) and R1.5 (a ROS 2 node's sentence: tests/ros2/test_live_fleet.py's run shows it),
    violates none, and every leaf has its tests."""
    run_dir = pour_run.run_dir
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "spec", "trace", str(run_dir)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "leaves: 8 shown, 4 not exercised (R1.2, R1.5, R2.1, R3.3), 0 violated" in proc.stdout, proc.stdout
    assert "tests: none" not in proc.stdout
    md = (run_dir / "report.md").read_text()
    assert "Requirements traced to this run" in md and "**violated**" not in md


# ---- roco replay (services/replay): each agent of the pour that takes only communicates ----

REPLAYED = ("a_co", "a_pl", "a_km", "a_ta")


def test_roco_replay_reproduces_what_each_agent_sent_in_the_pour(pour_run: PourRun) -> None:
    run_dir = pour_run.run_dir
    lines = replay_lines(run_dir)
    messages = load_run(run_dir).messages
    for agent in REPLAYED:
        sent = [m for m in messages if m.sender == agent and m.copy_of is None]
        got = [m for m in messages if m.rec.receivers[:1] == (agent,) and m.comm is not None]
        assert lines[agent] == f"{agent}: reproduced, {len(got)} inputs, {len(sent)} outputs", lines
    assert lines["a_hi"].startswith("a_hi: not replayed: ")


def test_the_presence_record_is_what_a_replayed_a_ta_needs(pour_run: PourRun, tmp_path: Path) -> None:
    """The recorder's presence record (services/recorder/presence.py): each agent's token seen
    to appear, the recorder's own first. a_ta subscribes to ag_ex's power-ons when
    ag_ex's token appears (after the world is up, after a_ta's first observe): with the record
    the replay reproduces that moment, the token taken no later than that subscription (the
    recorder may see the token after it: seen 3.4 ms after; tests/replay/test_when_it_came.py
    builds that order); without it (every agent alive from the start) the replayed a_ta
    subscribes first and differs."""
    from services.recorder.presence import read_presence
    from services.replay.driver import peers, replay
    from services.runtime.run_folder import TRAFFIC_JSONL
    from tests.support.recorded_run import PRESENCE_JSONL, copy_record

    events = read_presence(pour_run.run_dir)
    assert events is not None and events[0].name == "recorder", events  # the fleet starts it first
    appeared = {e.name for e in events if e.alive}
    assert appeared >= set(AGENTS) | {"recorder"}, events
    subscribe = next(
        m
        for m in load_run(pour_run.run_dir).messages
        if m.sender == "a_ta" and m.comm is not None and m.comm.performative.value == "subscribe"
    )
    assert subscribe.rec.t_sent is not None
    seen = peers(pour_run.run_dir, "a_ta")
    came = [c.t for c in seen.changes if c.name == "ag_ex" and c.alive]
    assert "ag_ex" in seen.initial or came[0] <= subscribe.rec.t_sent, (seen, subscribe.rec)

    bare = copy_record(pour_run.run_dir, tmp_path / "bare")
    (bare / PRESENCE_JSONL).unlink()
    assert (bare / TRAFFIC_JSONL).exists()
    result = replay(bare, "a_ta")
    assert not result.equal and any(d.field == "performative" for d in result.differences)


def test_an_answer_recorded_before_its_question_is_fed_after_it(pour_run: PourRun, tmp_path: Path) -> None:
    """a_pl's part of the pour's record rewritten so that a_km's answer to a_pl's first question
    comes before the request from a_co that made a_pl ask (as agents linked directly can reach
    the recorder; the run's record may hold that order already, or not): a_pl still reproduces,
    the answer held until the replayed a_pl has asked; fed in the record's order (the causal
    ordering off), a_pl answers it not-understood."""
    from services.replay.driver import render, replay
    from tests.support.recorded_run import STARTED, answer_before_its_cause, write_recorded_run

    messages = [
        m
        for m in load_run(pour_run.run_dir).messages
        if m.comm is not None and "a_pl" in (m.sender, *m.rec.receivers[:1])
    ]
    order, ask, answer = answer_before_its_cause(messages, "a_co", "a_pl", "a_km")
    at = [(ask if m is answer else m).rec.t - STARTED for m in order]  # the run's clock: reply-by
    traffic = [(t, m.comm) for t, m in zip(at, order, strict=True) if m.comm is not None]
    # each keeps its publisher's stamp: the recorder may see an answer after the question it
    # caused (agents linked directly), and the replay orders by what each sender had sent
    sent = [None if m.rec.t_sent is None else m.rec.t_sent - STARTED for m in order if m.comm is not None]
    moved = write_recorded_run(tmp_path / "run", traffic, sent=sent)
    result = replay(moved, "a_pl")
    assert result.equal, render(result)
    unordered = replay(moved, "a_pl", causal=False)
    assert not unordered.equal
    said = [d for d in unordered.differences if d.field == "performative"]
    assert said and said[0].replayed == "not-understood", render(unordered)


def test_roco_replay_reports_a_cost_a_pl_drew_at_random(
    pour_run: PourRun, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Nondeterminism planted in a_pl — a random amount added to every plan's cost — is a
    difference in the content of each plan a_pl sent, and nowhere else."""
    import random

    import services.agents.planner.agent as planner
    from services.replay.driver import render, replay

    to_hfsm = planner.to_hfsm

    def noisy(*args: object, **kwargs: object) -> tuple:
        root, complete, cost = to_hfsm(*args, **kwargs)  # type: ignore[arg-type]
        return root, complete, cost + random.uniform(0.5, 1.5)

    monkeypatch.setattr(planner, "to_hfsm", noisy)
    run_dir = pour_run.run_dir
    result = replay(run_dir, "a_pl")
    plans = [r.seq for r in read_records(run_dir) if r.sender == "a_pl" and r.performative == "inform"]
    assert len(plans) == 2
    assert [(d.seq, d.field) for d in result.differences] == [(s, "content.cost") for s in plans], render(
        result
    )
    assert all(0.5 <= float(d.replayed) - float(d.recorded) <= 1.5 for d in result.differences)


def test_what_if_ag_ex_ran_on_a_host_of_its_own(pour_run: PourRun) -> None:
    """``roco spec what-if`` on the pour (services/spec_check/whatif.py): with ag_ex alone on a
    host, only C5 crosses, every C5 communicate once, and the command's critical path crosses as
    often as the executions nested in it do (C3 stays on the brain)."""
    from services.spec.model import load
    from services.spec_check.placement import parse_placement
    from services.spec_check.whatif import what_if

    run_dir = pour_run.run_dir
    spec = load()
    w = what_if(run_dir, spec, parse_placement(spec.agent_names, "ag_ex | a_co a_pl a_km a_ta a_hi"), 0.02)
    assert {ch for flows in w.traffic.links.values() for ch in flows} == {"C5"}
    c5 = [r for r in read_records(run_dir) if r.channel == "C5"]
    assert sum(f.communicates for f in w.traffic.totals.values()) == len(c5)
    commands = [c for c in w.convs if c.kind == "C2:fipa-request"]
    executions = [c for c in w.convs if c.kind == "C1:coordinate"]
    assert len(commands) == 1 and executions
    assert w.paths.half_trips(commands[0]) == sum(w.paths.half_trips(c) for c in executions) > 0


@pytest.mark.parametrize("name", [n for n, case in forbidden.CASES.items() if case[0] not in forbidden.EXTRA])
def test_a_forbidden_conversation_appended_to_the_pour_s_record_is_flagged(
    pour_run: PourRun, name: str, tmp_path: Path
) -> None:
    """The planted faults of tests/spec_check/test_forbidden_conversations.py, each appended to
    this fresh pour's record: verify flags exactly its forbidden communicates, naming the
    conversation and the rule (the record itself verifies: the test above)."""
    protocol, steps, flagged = forbidden.CASES[name]
    run = forbidden.append_conversation(pour_run.run_dir, tmp_path / "run", "planted", protocol, steps)
    report = verify_run(run, default_spec())
    found = {v.position: v for v in report.violations}
    assert set(found) == set(flagged), [(v.position, v.kind, v.text) for v in report.violations]
    for position, words in flagged.items():
        assert found[position].conversation == "planted" and words in found[position].text
