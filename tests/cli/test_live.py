"""The live view (services/live/): its state folds the run's own observations —
communicates, ag_ex's state, liveliness tokens — into command, plan k of n, the step's place,
agents alive, sim against wall time and the loop's overrun share; the view draws them; the
watch takes them from Zenoh; off a terminal ``roco run`` keeps its plain lines."""

from __future__ import annotations

import io
import threading
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
import zenoh
from rich.console import Console
from typer.testing import CliRunner

import services.cli as cli
from services.cli.run_env import live_watch
from services.fleet.launcher import AGENT_ORDER
from services.live.state import LiveState
from services.live.view import LiveView
from services.live.watch import LiveWatch
from services.runtime import keys
from services.runtime.session import open_client
from services.spec.model import default_spec
from shared.fipa_codec import Performative, encode
from shared.fipa_codec.languages import extend
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, Notice, Severity, TaskAtom
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanNode
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.codec_registry import languages_restored
from tests.support.messages import communicate
from tests.support.notice_agents import Fallen
from tests.support.router import embedded_router
from velma.executor.state import RobotSnapshot
from velma.executor.timing import TimingStats

AGENTS = ("a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi")
PLAN_1 = HierarchicalPlan(
    plan_id="p1",
    task_id="t1",
    complete=False,
    root=PlanNode(
        name="pour",
        children=(
            PlanNode(name="fetch_jar", children=(PlanNode(name="grasp"), PlanNode(name="lift"))),
            PlanNode(name="look_at_bowl"),
        ),
    ),
)
PLAN_2 = HierarchicalPlan(
    plan_id="p2", task_id="t1", root=PlanNode(name="pour", children=(PlanNode(name="tilt"),))
)


def wire(channel: str, sender: str, receiver: str, term: msgspec.Struct) -> tuple[str, bytes]:
    perf = Performative.INFORM if isinstance(term, SWStatus | HierarchicalPlan) else Performative.REQUEST
    msg = communicate(perf, sender, receiver, "fipa-request", "c1", term)
    return keys.fipa_key(channel, sender, receiver), encode(msg)


def snapshot(sim_time: float, overruns: int = 0, cycles: int = 0) -> bytes:
    timing = TimingStats(
        pacing="fast",
        cycles=cycles,
        window=1000,
        compute_p50_us=300.0,
        compute_p99_us=550.0,
        compute_max_us=900.0,
        lateness_p50_us=0.0,
        lateness_p99_us=0.0,
        lateness_max_us=0.0,
        overruns=overruns,
        overrun_share=overruns / cycles if cycles else 0.0,
        max_consecutive_overruns=1,
        sim_time=sim_time,
    )
    snap = RobotSnapshot(
        sim_time=sim_time, joints={"torso_0_joint": 0.1}, grip={}, held={}, held_object={}, timing=timing
    )
    return msgspec.msgpack.encode(snap)


def test_the_state_follows_command_plans_steps_agents_and_clocks() -> None:
    state = LiveState(AGENTS, started=100.0)
    empty = state.progress(100.0)
    assert empty.command is None and empty.plan is None and empty.sim_s is None
    for agent in AGENTS:
        state.alive(agent, True)
    state.communicate(
        *wire("C2", "a_hi", "a_co", HumanCommand(text="pour the jar into the bowl", goal=TaskAtom("pour")))
    )
    state.communicate(*wire("C3", "a_co", "a_pl", GroundTaskNetwork(task_id="t1", tasks=(), plan_index=1)))
    state.communicate(*wire("C3", "a_pl", "a_co", PLAN_1))
    state.communicate(*wire("C1", "a_co", "a_ta", PLAN_1))  # the same plan again, on C1
    state.communicate(
        *wire("C1", "a_ta", "a_co", SWStatus(state=SWState.RUNNING, plan_id="p1", step="pour/fetch_jar/lift"))
    )
    state.robot_state(snapshot(2.0, overruns=1, cycles=2000), wall=104.0)
    state.robot_state(snapshot(6.0, overruns=3, cycles=6000), wall=106.0)
    state.alive("a_km", False)
    p = state.progress(110.0)
    assert p.command == "pour the jar into the bowl" and p.commands == 1
    assert p.plan is not None and (p.plan.index, p.plan.of, p.plan.complete) == (1, "≥ 2", False)
    assert p.step == "pour/fetch_jar/lift" and p.step_place == (2, 3) and p.sw_state == "Running"
    assert p.alive == frozenset(AGENTS) - {"a_km"}
    assert (p.wall_s, p.sim_s, p.sim_rate) == (10.0, 6.0, 2.0)
    assert p.overrun_share == pytest.approx(0.0005) and (p.overruns, p.cycles) == (3, 6000)

    # plan #2 completes the task; a step outside the plan (a safe stop's) has no place
    state.communicate(*wire("C3", "a_co", "a_pl", GroundTaskNetwork(task_id="t1", tasks=(), plan_index=2)))
    state.communicate(*wire("C3", "a_pl", "a_co", PLAN_2))
    state.communicate(
        *wire("C1", "a_ta", "a_co", SWStatus(state=SWState.RUNNING, plan_id="p2", step="pour/tilt"))
    )
    p = state.progress(111.0)
    assert p.plan is not None and (p.plan.index, p.plan.of) == (2, "2") and p.step_place == (1, 1)
    state.communicate(
        *wire("C1", "a_ta", "a_co", SWStatus(state=SWState.TERMINATING, plan_id="p2", step="stop/put_down"))
    )
    assert state.progress(112.0).step_place is None
    state.communicate(
        *wire("C2", "a_co", "a_hi", CommandOutcome(command_id="t1", succeeded=True, detail="18/18"))
    )
    assert state.progress(113.0).outcome == "succeeded: 18/18"
    # what is not a communicate, or not a state, changes nothing
    state.communicate("roco/human/out", b"\x00")
    state.robot_state(b"not msgpack", wall=120.0)
    assert state.progress(113.0).sim_s == 6.0


def test_an_executor_restart_restarts_the_sim_rate() -> None:
    state = LiveState(AGENTS, started=0.0)
    state.robot_state(snapshot(50.0), wall=10.0)
    state.robot_state(snapshot(60.0), wall=20.0)
    state.robot_state(snapshot(1.0), wall=30.0)  # a new ag_ex starts its clock again
    state.robot_state(snapshot(3.0), wall=31.0)
    assert state.progress(31.0).sim_rate == 2.0


def test_the_view_shows_every_row() -> None:
    state = LiveState(AGENTS, started=0.0)
    state.alive("a_hi", True)
    state.communicate(
        *wire("C2", "a_hi", "a_co", HumanCommand(text="pour the jar into the bowl", goal=TaskAtom("pour")))
    )
    state.communicate(*wire("C3", "a_pl", "a_co", PLAN_1))
    state.communicate(
        *wire("C1", "a_ta", "a_co", SWStatus(state=SWState.RUNNING, plan_id="p1", step="pour/fetch_jar/lift"))
    )
    state.robot_state(snapshot(4.0, overruns=5, cycles=4000), wall=1.0)
    state.robot_state(snapshot(8.0, overruns=5, cycles=8000), wall=3.0)
    out = io.StringIO()
    Console(file=out, width=100, color_system=None).print(LiveView("roco run", state.progress(5.0)))
    text = out.getvalue()
    for expected in (
        "roco run",
        "#1 “pour the jar into the bowl”",
        "#1 of ≥ 2 (partial, ends with sensing)",
        "2 of 3",
        "pour/fetch_jar/lift",
        "Running",
        "1 of 6 alive",
        "not: a_km, a_pl, a_co, ag_ex, a_ta",
        "wall    5.0 s · sim    8.0 s  (2.00 × wall time)",
        "overruns 0.062 % (5 of 8,000 cycles)",
    ):
        assert expected in text, (expected, text)


def test_the_view_shows_the_last_notice_to_the_person_with_its_sender() -> None:
    """A notice (protocol roco-notify, sent to a_hi for the person) is shown with who sent it, from
    the communicate's key; none, no row."""
    state = LiveState(AGENTS, started=0.0)
    assert "notice" not in dict(LiveView("roco run", state.progress(1.0)).rows())
    for text in ("the cup is gone", "the jar tipped over"):
        msg = communicate(
            Performative.INFORM,
            "a_wt",
            "a_hi",
            "roco-notify",
            "n",
            Notice(text=text, severity=Severity.WARNING),
        )
        state.communicate(keys.fipa_key("C9", "a_wt", "a_hi"), encode(msg))
    p = state.progress(1.0)
    assert (p.notice, p.notices) == ("a_wt (warning): the jar tipped over", 2)
    out = io.StringIO()
    Console(file=out, width=120, color_system=None).print(LiveView("roco run", p))
    assert "notice   a_wt (warning): the jar tipped over  (2 in all)" in out.getvalue()


def test_an_inform_of_a_notice_protocol_is_shown_as_the_term_says_itself_and_another_is_not() -> None:
    """An inform of a notice protocol (here ``kitchen-warning``) carrying a term of the sender's
    own is shown by its ``told()`` (shared/fipa_codec/languages/told.py); an inform of another
    protocol carrying the same term is no notice."""
    state = LiveState(AGENTS, started=0.0, notice_protocols=frozenset({"kitchen-warning"}))
    with languages_restored():
        extend("L_HC", Fallen)
        for protocol in ("kitchen-warning", "fipa-subscribe"):
            msg = communicate(
                Performative.INFORM, "a_wt", "a_hi", protocol, "n", Fallen(object=protocol, tilt_deg=90.0)
            )
            state.communicate(keys.fipa_key("C10", "a_wt", "a_hi"), encode(msg))
    p = state.progress(1.0)
    assert (p.notice, p.notices) == ("a_wt: the kitchen-warning has tipped over", 1)


@pytest.fixture(scope="module")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """An embedded router on a free loopback port (tests/support/router.py)."""
    yield from embedded_router(tmp_path_factory, "live")


def test_the_watch_takes_traffic_state_and_tokens_from_zenoh(router: str) -> None:
    out = io.StringIO()
    watch = LiveWatch("roco run", AGENTS, console=Console(file=out, width=100, force_terminal=True))
    seen = {"communicate": threading.Event(), "robot_state": threading.Event(), "alive": threading.Event()}
    for name, event in seen.items():
        original = getattr(watch.state, name)

        def spy(*args: object, _original: object = original, _event: threading.Event = event) -> None:
            _original(*args)  # type: ignore[operator]
            _event.set()

        setattr(watch.state, name, spy)
    listener, speaker = open_client(router), open_client(router)
    try:
        with watch:
            watch.attach(listener)
            token = speaker.liveliness().declare_token(keys.alive_key("a_co"))
            # the subscribers are declared; put until each kind has arrived once
            key, payload = wire(
                "C2", "a_hi", "a_co", HumanCommand(text="bring the cup", goal=TaskAtom("bring"))
            )
            for _ in range(100):
                speaker.put(key, payload)
                speaker.put(keys.state_key("ag_ex"), snapshot(1.5, overruns=2, cycles=1500))
                if seen["communicate"].wait(0.05) and seen["robot_state"].wait(0.05):
                    break
            assert seen["alive"].wait(10.0)
            watch.line("[   1.0 s] an event line")
            p = watch.state.progress(watch.clock())
            token.undeclare()
    finally:
        speaker.close()
        listener.close()
    assert p.command == "bring the cup" and p.sim_s == 1.5 and p.overruns == 2
    assert "a_co" in p.alive
    text = out.getvalue()
    assert "[   1.0 s] an event line" in text and "bring the cup" in text


def test_off_a_terminal_or_quiet_there_is_no_live_view(monkeypatch: pytest.MonkeyPatch) -> None:
    kitchen = default_spec()
    assert live_watch("roco run", None, quiet=False, system=kitchen) is None  # stdout is no terminal
    assert live_watch("roco run", True, quiet=True, system=kitchen) is not None  # asked for
    monkeypatch.setenv("FORCE_COLOR", "1")
    monkeypatch.setenv("TTY_COMPATIBLE", "1")
    assert live_watch("roco run", None, quiet=True, system=kitchen) is None
    assert live_watch("roco run", False, quiet=False, system=kitchen) is None
    watch = live_watch("roco chaos", True, quiet=False, system=kitchen)
    assert watch is not None and watch.state.expected == tuple(AGENT_ORDER)


def test_run_with_live_hands_the_watch_its_session_and_lines(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """``roco run --live`` gives the scenario runner the watch's ``attach`` and ``line``."""
    given: dict[str, object] = {}

    class Runner:
        def __init__(self, sc: object, run_dir: Path, **kwargs: object) -> None:
            given.update(kwargs)

        def run(self) -> object:
            raise KeyboardInterrupt  # stop before anything starts

    monkeypatch.setattr("services.scenario.runner.ScenarioRunner", Runner)
    monkeypatch.setattr("signal.signal", lambda *args: None)  # pytest keeps its SIGTERM
    result = CliRunner().invoke(
        cli.app, ["run", "pour the jar into the bowl", "--live", "--runs-dir", str(tmp_path)]
    )
    assert result.exit_code == 130  # the interrupt, as roco's main would exit
    on_session, echo = given["on_session"], given["echo"]
    assert getattr(on_session, "__func__", None) is LiveWatch.attach
    assert callable(echo)
    plain: dict[str, object] = {}
    given.clear()
    CliRunner().invoke(cli.app, ["run", "pour", "--runs-dir", str(tmp_path)])
    plain.update(given)
    assert plain["on_session"] is None


def test_a_real_snapshot_decodes_as_the_glance() -> None:
    """The view reads two fields of ag_ex's RobotSnapshot: the whole message decodes."""
    state = LiveState(AGENTS, started=0.0)
    state.robot_state(snapshot(12.5, overruns=7, cycles=12500), wall=1.0)
    p = state.progress(2.0)
    assert (p.sim_s, p.overruns, p.cycles) == (12.5, 7, 12500)


_ = zenoh  # the watch's sessions are zenoh's
