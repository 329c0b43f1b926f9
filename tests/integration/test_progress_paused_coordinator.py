"""Every progress step reaches the person although a_co is paused for 10 s at its start-up
(services/fault/process.py, as ``roco fault pause``): a_hi's subscribe and the person's
command find no a_co listening, a_co takes the command when it runs again, before any
subscription is agreed, and what it reports meanwhile must still reach the person
(services/agents/coordinator/agent.py; FIPA SC00035). One pour, with the kinematic robot double
as ag_ex (tests/support/kinematic_ex.py: the progress is the subject, not the robot); the router
on a free loopback port, every service a process of its own."""

from __future__ import annotations

import queue
import re
import time
from pathlib import Path

import msgspec
import pytest
import zenoh

from services.fault import process
from services.fleet.launcher import AGENT_ORDER, Fleet, free_port
from services.recorder.sync import sync
from services.report.load import load_run
from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from services.runtime.session import alive_agents, open_client
from services.spec.model import default_spec
from services.spec_check.conformance import render, verify_run
from shared.fipa_codec import Performative, decode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.kinematic_ex import kinematic_spec, ran_kinematic

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]

PAUSE_S = 10.0
"""How long a_co stays paused from its start (s)."""
COMMAND = "pour the jar into the bowl"


class Person:
    """What the test's session hears: a_hi's reports, and a_ta's first world update to a_km
    (a_km has the initial knowledge of the scene, paper Table 7)."""

    def __init__(self, session: zenoh.Session) -> None:
        self.events: queue.SimpleQueue[HumanReport | None] = queue.SimpleQueue()
        self.reports: list[HumanReport] = []
        session.declare_subscriber(keys.HUMAN_OUT, self._report)
        session.declare_subscriber(keys.fipa_key("C6", "a_ta", "a_km"), self._update)

    def _report(self, sample: zenoh.Sample) -> None:
        self.events.put(msgspec.json.decode(sample.payload.to_bytes(), type=HumanReport))

    def _update(self, sample: zenoh.Sample) -> None:
        if any(decode(p).performative is Performative.INFORM for p in unpack(sample.payload.to_bytes())):
            self.events.put(None)

    def listen(self, until: float, *, knowledge: bool = False, final: bool = False) -> bool:
        """Take what arrives until the monotonic time ``until``; stop early (True) at the
        initial knowledge (``knowledge``) or at the command's final report (``final``)."""
        while (left := until - time.monotonic()) > 0:
            try:
                event = self.events.get(timeout=left)
            except queue.Empty:
                break
            if event is None:
                if knowledge:
                    return True
                continue
            self.reports.append(event)
            if final and event.kind in FINAL_REPORTS:
                return True
        return False


def in_order(wanted: list[str], seen: list[str]) -> list[str]:
    """The items of ``wanted`` that ``seen`` lacks when both are read in order (each found
    after the one found before it)."""
    missing, at = [], 0
    for w in wanted:
        try:
            at = seen.index(w, at) + 1
        except ValueError:
            missing.append(w)
    return missing


def test_every_progress_step_reaches_the_person_with_a_co_paused_at_its_start(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    (run_dir / "logs").mkdir(parents=True)
    spec = kinematic_spec(tmp_path / "kinematic.toml")
    env = {"ROCO_SPEC": str(spec), "PYTHONPATH": str(ROOT), "ROCO_REALTIME": "0", "ROCO_RERUN": "0"}
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", env=env)
    session: zenoh.Session | None = None
    paused = False
    try:
        fleet.start_router()
        session = open_client(fleet.endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        person = Person(session)
        first = [a for a in AGENT_ORDER if a not in ("a_co", "a_hi")]
        fleet.start_agents(first)
        fleet.wait_alive(session, first, timeout=120)
        assert person.listen(time.monotonic() + 60, knowledge=True), "a_km got no initial knowledge"
        # a_co paused as it starts, before it listens; a_hi starts meanwhile and subscribes
        fleet.start_agents(["a_co"])
        faults = [process.pause(fleet, "a_co")]
        paused, paused_at = True, time.monotonic()
        fleet.start_agents(["a_hi"])
        fleet.wait_alive(session, ["a_hi"], timeout=120)
        assert "a_co" not in alive_agents(session)
        said = HumanInput(text=COMMAND, request_id="pour")
        session.put(keys.HUMAN_IN, msgspec.json.encode(said))
        assert not person.listen(paused_at + PAUSE_S, final=True), [r.text for r in person.reports]
        faults.append(process.unpause(fleet, "a_co"))
        paused = False
        assert process.record_events(session, faults)
        assert person.listen(time.monotonic() + 300, final=True), [r.text for r in person.reports]
        assert sync(session, 30.0)  # the traffic record holds everything routed so far
    finally:
        if paused:
            process.unpause(fleet, "a_co")
        if session is not None:
            session.close()
        fleet.stop()

    assert ran_kinematic(run_dir)
    mine = [r for r in person.reports if r.request_id == "pour"]
    assert mine[-1].kind is ReportKind.SUCCEEDED, [r.text for r in mine]
    progress = [r.text for r in mine if r.kind is ReportKind.PROGRESS]
    messages = load_run(run_dir).messages
    # every step a_ta ran, of every plan, in order (a_hi shows a change once: a step reported
    # twice in a row is one change)
    steps: list[str] = []
    for m in messages:
        c = m.content
        if not (m.is_("C1", "a_ta", "inform") and isinstance(c, SWStatus)):
            continue
        if c.state is SWState.RUNNING and c.step and (not steps or steps[-1] != c.step):
            steps.append(c.step)
    assert len(steps) >= 20, steps  # a pour's plans run dozens of steps
    shown = [s for text in progress for s in re.findall(r"\brunning (\S+)", text)]
    missing = in_order(steps, shown)
    assert not missing, f"not shown: {missing}\nshown:\n" + "\n".join(progress)
    # every plan a_co asked a_pl for, and every plan a_pl made, was told
    asked = sorted({m.conversation for m in messages if m.is_("C3", "a_co", "request")}, key=str)
    made = sorted({m.conversation for m in messages if m.is_("C3", "a_pl", "inform")}, key=str)
    assert len(made) >= 1 and set(made) <= set(asked)
    for conversation in asked:
        n = str(conversation).rsplit("plan", 1)[1]
        assert any(f"plan #{n} requested" in t for t in progress), (n, progress)
    for conversation in made:
        n = str(conversation).rsplit("plan", 1)[1]
        assert any(f"plan #{n} ready" in t for t in progress), (n, progress)
    # the traffic follows the specification, but for the subscribes a_hi sent while no a_co
    # listened: never agreed nor refused, they are violations (and only they)
    report = verify_run(run_dir, default_spec())
    unanswered = [v for v in report.violations if v.kind == "unanswered"]
    assert report.violations == unanswered, render(report)
    assert all(v.protocol == "fipa-subscribe" and v.sender == "a_hi" for v in unanswered)
