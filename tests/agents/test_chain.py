"""The five agents and ag_ex's communication side, in one process on a MemoryBus with a
kinematic test double of the robot: the protocols of paper §5.4 carry a pour to the end."""

from __future__ import annotations

import math
from collections.abc import Callable

import msgspec
import pytest

from services.runtime.human import ReportKind
from shared.fipa_codec import Communicate, decode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import CommandResult, ExecutorCommand, LookAt, Observe, Release, Tilt
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.fake_executor import PARTICLES, FakeExecutor
from tests.support.memory_fleet import MemoryFleet


def _traffic(fleet: MemoryFleet) -> list[tuple[str, tuple[Communicate, msgspec.Struct | None]]]:
    out = []
    for key, payload in fleet.bus.published:
        if not key.startswith("roco/fipa/"):
            continue
        msg = decode(payload)
        content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
        out.append((key, (msg, content)))
    return out


@pytest.mark.requirement("R2.1", "R2.2")
def test_pour_runs_two_plans_and_succeeds() -> None:
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("fill the bowl from the jar")  # a pour in other words
        traffic = _traffic(fleet)
    kinds = [r.kind for r in reports if r.kind is not ReportKind.PROGRESS]
    assert kinds == [ReportKind.ACCEPTED, ReportKind.SUCCEEDED]
    assert any(r.kind is ReportKind.PROGRESS for r in reports)  # the person sees progress
    assert fleet.executor.inside["jar"] == 0 and fleet.executor.inside["bowl"] == PARTICLES
    plans = [
        c
        for _, (m, c) in traffic
        if isinstance(c, HierarchicalPlan) and m.sender is not None and m.sender.name == "a_pl"
    ]
    assert [p.complete for p in plans] == [False, True]
    assert all(p.km_queries > 0 for p in plans)
    states = [c.state for k, (m, c) in traffic if isinstance(c, SWStatus)]
    assert states.count(SWState.REPLAN) == 1 and states[-1] is SWState.SUCCEEDED
    channels = {k.split("/")[2] for k, _ in traffic}
    assert channels == {"C1", "C2", "C3", "C4", "C5", "C6", "C7"}  # C7: a_hi asks a_km for its words
    # every L_SW inform of a_ta is confirmed by a_co (paper §5.4)
    informs = [m.reply_with for k, (m, c) in traffic if isinstance(c, SWStatus)]
    confirms = {m.in_reply_to for k, (m, c) in traffic if m.performative.value == "confirm"}
    assert set(informs) <= confirms


def test_unknown_sentence_is_reported_not_understood() -> None:
    with MemoryFleet() as fleet:
        reports = fleet.command("sing me a song")
    assert [r.kind for r in reports] == [ReportKind.NOT_UNDERSTOOD]
    assert "pour the jar into the bowl" in reports[0].text


def test_unknown_object_fails_with_a_readable_reason() -> None:
    """a_hi names the word a_km's knowledge has no thing for."""
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("pour the teapot into the bowl")
    assert reports[-1].kind is ReportKind.NOT_UNDERSTOOD
    assert "'teapot'" in reports[-1].text


def test_executor_failure_ends_the_task_with_error() -> None:
    with MemoryFleet(FakeExecutor(fail={"Grasp"})) as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("pour the jar into the bowl")
    assert reports[-1].kind is ReportKind.FAILED
    assert "grasp" in reports[-1].text and "injected failure" in reports[-1].text


def test_fleet_serves_a_second_command_after_the_first() -> None:
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        first = fleet.command("pour the jar into the bowl", request_id="r1")
        second = fleet.command("pour the jar into the bowl", request_id="r2")
    assert first[-1].kind is ReportKind.SUCCEEDED
    # the jar is now empty and held: the second pour still runs and the check still passes
    assert second[-1].kind is ReportKind.SUCCEEDED


class _TippingExecutor(FakeExecutor):
    """Lets go of the bowl and it falls over (a person knocks it, or it slides off): on its
    side, 90° about x, where it was put."""

    def submit(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> None:
        dropped = self.held[command.arm.value] if isinstance(command, Release) else None
        super().submit(command, on_done)
        if dropped == "bowl":
            half = math.sqrt(0.5)
            self.poses["bowl"] = Pose(self.poses["bowl"].position, (half, half, 0.0, 0.0))


def test_a_placement_is_judged_by_the_world_it_left() -> None:
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        upright = fleet.command("bring me the bowl")
    assert upright[-1].kind is ReportKind.SUCCEEDED
    with MemoryFleet(_TippingExecutor()) as fleet:
        fleet.wait_for_initial_knowledge()
        tipped = fleet.command("bring me the bowl")
    assert tipped[-1].kind is ReportKind.FAILED
    assert "the bowl is not upright: it leans 90°" in tipped[-1].text


class _BlurryExecutor(FakeExecutor):
    """The first look at the jar alone is uncertain (σ 20 mm); a later one sees it sharply
    if the head has just turned to it again (LookAt); with ``stays_blurry`` it stays
    uncertain."""

    def __init__(self, stays_blurry: bool = False) -> None:
        super().__init__()
        self.stays_blurry = stays_blurry
        self.looked = False
        self.jar_looks = 0

    def submit(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> None:
        looked, self.looked = self.looked, isinstance(command, LookAt)  # the command just before
        if not (isinstance(command, Observe) and command.objects == ("jar",)):
            super().submit(command, on_done)
            return
        self.jar_looks += 1
        sigma = 0.02 if self.stays_blurry or not looked or self.jar_looks == 1 else 0.001
        box: list[CommandResult | Observation] = []
        super().submit(command, box.append)
        (obs,) = box
        assert isinstance(obs, Observation)
        blurred = tuple(msgspec.structs.replace(o, position_sigma=sigma) for o in obs.objects)
        on_done(msgspec.structs.replace(obs, objects=blurred))


def test_an_uncertain_object_is_looked_at_again_before_the_grasp() -> None:
    with MemoryFleet(_BlurryExecutor()) as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("bring me the jar")
        sent = fleet.executor.commands
    assert reports[-1].kind is ReportKind.SUCCEEDED
    first = next(i for i, c in enumerate(sent) if isinstance(c, Observe) and c.objects == ("jar",))
    assert isinstance(sent[first + 1], LookAt) and sent[first + 2] == sent[first]  # a second view
    with MemoryFleet(_BlurryExecutor(stays_blurry=True)) as fleet:
        fleet.wait_for_initial_knowledge()
        fleet.command("bring me the jar")
        reasons = [
            c.reason or ""
            for k, (m, c) in _traffic(fleet)
            if isinstance(c, SWStatus) and c.state is SWState.REPLAN
        ]
    assert any("the jar's position is too uncertain to grasp (σ 20 mm)" in r for r in reasons), reasons


class _ShortCountExecutor(FakeExecutor):
    """The bowl's content is counted ``short`` spheres low on every look at the bowl alone
    except one made right after the head turned to it (LookAt), unless ``stays_short``."""

    def __init__(self, short: int, stays_short: bool = False) -> None:
        super().__init__()
        self.short, self.stays_short = short, stays_short
        self.looked = False

    def submit(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> None:
        looked, self.looked = self.looked, isinstance(command, LookAt)  # the command just before
        counted_again = looked and not self.stays_short
        if not (isinstance(command, Observe) and command.objects == ("bowl",)) or counted_again:
            super().submit(command, on_done)
            return
        box: list[CommandResult | Observation] = []
        super().submit(command, box.append)
        (obs,) = box
        assert isinstance(obs, Observation)
        low = tuple(
            msgspec.structs.replace(o, particles_inside=max(0, (o.particles_inside or 0) - self.short))
            for o in obs.objects
        )
        on_done(msgspec.structs.replace(obs, objects=low))


def _content_checks(sent: list[ExecutorCommand]) -> list[int]:
    return [i for i, c in enumerate(sent) if isinstance(c, Observe) and c.objects == ("bowl",)]


def test_a_short_content_count_is_looked_at_again_and_the_second_count_judges() -> None:
    with MemoryFleet(_ShortCountExecutor(short=3)) as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("pour the jar into the bowl")
        sent = fleet.executor.commands
    assert reports[-1].kind is ReportKind.SUCCEEDED, reports[-1].text
    last = _content_checks(sent)[-1]
    assert isinstance(sent[last - 1], LookAt) and sent[last - 2] == sent[last]  # look, then count again
    with MemoryFleet(_ShortCountExecutor(short=3, stays_short=True)) as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("pour the jar into the bowl")
        sent = fleet.executor.commands
    assert reports[-1].kind is ReportKind.FAILED
    assert f"bowl holds only {round(100 * (PARTICLES - 3) / PARTICLES)} % of the content" in reports[-1].text
    checks = _content_checks(sent)
    second_views = [i for i in checks if isinstance(sent[i - 1], LookAt) and sent[i - 2] == sent[i]]
    assert second_views == [checks[-1]]  # one second view, then the task fails


def test_it_names_the_object_the_person_named_last() -> None:
    """Saying “put it on the table” after a command about the cup moves the cup."""
    with MemoryFleet() as fleet:
        fleet.wait_for_initial_knowledge()
        start = fleet.executor.poses["cup"].position
        first = fleet.command("pick up the cup", request_id="r1")
        second = fleet.command("now put it on the table", request_id="r2")
        end = fleet.executor.poses["cup"].position
    assert first[-1].kind is ReportKind.SUCCEEDED, first[-1].text
    assert second[-1].kind is ReportKind.SUCCEEDED, second[-1].text
    assert second[-1].text.startswith("put the cup on the table: succeeded")
    assert end != start and not fleet.executor.held.get("right")


@pytest.mark.requirement("R2.2", "R2.3")
def test_a_plan_whose_pour_the_target_cannot_take_is_not_run_and_the_person_hears_why() -> None:
    """a_km refuses plan #2 at its pour step (the bowl already holds 70 of its 84); a_pl sends
    no plan, and a_hi tells the person the step and the reason; nothing is poured."""
    executor = FakeExecutor()
    executor.inside["bowl"] = 70
    with MemoryFleet(executor) as fleet:
        fleet.wait_for_initial_knowledge()
        reports = fleet.command("pour the jar into the bowl")
        traffic = _traffic(fleet)
    assert reports[-1].kind is ReportKind.FAILED
    assert reports[-1].text.endswith(
        "the plan cannot work: step 6 pour(jar, bowl): the bowl cannot take what the jar holds: "
        f"{PARTICLES} particles into 70, capacity 84"
    )
    plans = [
        c
        for _, (m, c) in traffic
        if isinstance(c, HierarchicalPlan) and m.sender is not None and m.sender.name == "a_pl"
    ]
    assert [p.complete for p in plans] == [False]  # plan #1 ran; plan #2 was not sent
    assert executor.inside == {"jar": PARTICLES, "bowl": 70, "cup": 0}
    assert not any(isinstance(c, Tilt) for c in executor.commands)
