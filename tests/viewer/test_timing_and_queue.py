"""The control loop's timing (from ag_ex's snapshots) and a_co's command queue (a_co's own part
of the recording) in Rerun; read back from the merged recording."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from services.viewer import hooks, recording, robot, tasks
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_hc import Status, TaskState, TaskStatus
from tests.support.rerun_run import rerun_run_dir
from tests.viewer.test_recording import rows, values
from velma.executor.state import RobotSnapshot
from velma.executor.timing import TimingStats

RUN = "20261121-140000-queue"


@pytest.fixture
def run_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    return rerun_run_dir(tmp_path / RUN, monkeypatch)


def stats(cycles: int, overruns: int, p99: float) -> TimingStats:
    return TimingStats(
        pacing="realtime",
        cycles=cycles,
        window=min(cycles, 120_000),
        compute_p50_us=380.0,
        compute_p99_us=p99,
        compute_max_us=2 * p99,
        lateness_p50_us=0.5,
        lateness_p99_us=3.0,
        lateness_max_us=40.0,
        overruns=overruns,
        overrun_share=overruns / cycles,
        max_consecutive_overruns=min(overruns, 3),
        sim_time=cycles / 1000,
    )


def snap(t: float, timing: TimingStats | None) -> RobotSnapshot:
    return RobotSnapshot(
        sim_time=t,
        joints={"torso_0_joint": 0.0},
        grip={"right": Pose(position=(0.5, 0.0, 1.0))},
        held={"right": False},
        held_object={"right": None},
        timing=timing,
    )


def test_timing_is_logged_once_per_new_statistics(run_dir: Path) -> None:
    hook = hooks.robot_hook("ag_ex", run_dir)
    assert hook is not None
    first, second = stats(1000, 2, 700.0), stats(2000, 5, 720.0)
    # ag_ex attaches the same statistics to every snapshot until it recomputes them (≈ 1 s)
    for i, timing in enumerate([None, first, first, first, second, second]):
        hook.snapshot(snap(0.05 * i, timing))
    hook.close()
    merged = recording.merge_parts(run_dir)
    assert merged is not None
    counts = rows(merged)
    series = [f"{kind}/{q}" for kind in ("compute", "lateness") for q in ("p50", "p99", "max")]
    series += ["overruns/count", "overruns/share_percent", "overruns/max_consecutive"]
    for name in series:
        assert counts[f"/{robot.TIMING}/{name}"] == 2, name
    assert values(merged, f"/{robot.TIMING}/compute/p99", "Scalars:scalars") == [700.0, 720.0]
    assert values(merged, f"/{robot.TIMING}/overruns/count", "Scalars:scalars") == [2.0, 5.0]
    share = values(merged, f"/{robot.TIMING}/overruns/share_percent", "Scalars:scalars")
    assert share == pytest.approx([0.2, 0.25])


def status(*rows_: tuple[str, str, TaskState, int]) -> Status:
    return Status(tasks=tuple(TaskStatus(command_id=i, text=t, state=s, priority=p) for i, t, s, p in rows_))


def test_queue_rows_are_logged_when_the_queue_changes(run_dir: Path) -> None:
    hook = hooks.queue_hook("a_co", run_dir)
    assert hook is not None
    pour = ("pour", "pour the jar into the bowl", TaskState.RUNNING, 0)
    cup = ("cup", "urgently bring the cup | now", TaskState.WAITING, 5)
    sequence = [
        status(("pour", pour[1], TaskState.WAITING, 0)),
        status(pour),
        status(pour),  # no change: not logged
        status(pour, cup),
        status(("cup", cup[1], TaskState.RUNNING, 5), ("pour", pour[1], TaskState.PREEMPTED, 0)),
        status(("cup", cup[1], TaskState.SUCCEEDED, 5), ("pour", pour[1], TaskState.PREEMPTED, 0)),
        status(("pour", pour[1], TaskState.PREEMPTED, 0)),  # the same queue once cup is gone
        status(("pour", pour[1], TaskState.SUCCEEDED, 0)),
        status(),  # ended commands are not in the queue: no change
    ]
    for i, st in enumerate(sequence):
        hook.logger.queue(st, wall=1_790_000_000.0 + i)
    hook.close()
    merged = recording.merge_parts(run_dir)
    assert merged is not None
    counts = rows(merged)
    assert counts[f"/{tasks.QUEUE}"] == 6
    assert values(merged, f"/{tasks.LENGTH}", "Scalars:scalars") == [1.0, 1.0, 2.0, 2.0, 1.0, 0.0]
    docs = values(merged, f"/{tasks.QUEUE}", "TextDocument:text")
    assert docs[0].splitlines()[2] == "| pour | pour the jar into the bowl | 0 | — | waiting |"
    preempted = docs[3].splitlines()
    assert preempted[2].startswith("| cup | urgently bring the cup \\| now | 5 |")
    assert preempted[2].endswith("| running |") and preempted[3].endswith("| preempted |")
    assert docs[-1] == "*empty*"
    media = values(merged, f"/{tasks.QUEUE}", "TextDocument:media_type")
    assert set(media) == {"text/markdown"}


def test_a_failing_queue_hook_switches_itself_off(run_dir: Path) -> None:
    hook = hooks.queue_hook("a_co", run_dir)
    assert hook is not None

    def broken(status: Status, **_: Any) -> bool:
        raise RuntimeError("disk full")

    hook.logger.queue = broken  # type: ignore[method-assign]
    hook.queue(status(("r1", "pour", TaskState.WAITING, 0)))  # does not raise
    assert hook.failed
    hook.queue(status())  # and is a no-op from now on
    hook.close()


def test_queue_logging_is_off_by_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from services.agents.coordinator.agent import Coordinator
    from services.runtime.memory_transport import MemoryBus

    monkeypatch.delenv("ROCO_RERUN", raising=False)
    monkeypatch.setenv("ROCO_RUN_DIR", str(tmp_path))
    assert hooks.queue_hook("a_co", tmp_path) is None
    assert Coordinator(MemoryBus().transport()).rerun is None
    assert not (tmp_path / recording.PARTS_DIR).exists()


def test_a_co_logs_its_queue_through_a_preemption(run_dir: Path) -> None:
    """The pour is preempted by an urgent command (as in tests/agents/test_coordination.py):
    a_co's part shows both commands queued, the pour preempted while the cup runs, then
    nothing."""
    from services.runtime.human import ReportKind
    from tests.agents.test_coordination import GatedExecutor, Session, interrupt_pour, is_cancel_to_ta
    from tests.agents.test_coordination import turning_to_pour as gate

    robot_double = GatedExecutor(gate)
    with Session(robot_double) as s:
        interrupt_pour(s, robot_double, "urgently bring the cup to the table", "cup")
        s.wait_for(is_cancel_to_ta)
        robot_double.release()
        assert s.final("cup").kind is ReportKind.SUCCEEDED
        assert s.final("pour").kind is ReportKind.SUCCEEDED
    for name in ("a_co", "ag_ex"):
        s.agent(name).close()  # type: ignore[attr-defined]
    parts = sorted(p.name.split("-")[0] for p in recording.parts(run_dir))
    assert parts == ["a_co", "ag_ex"]
    merged = recording.merge_parts(run_dir)
    assert merged is not None
    docs = values(merged, f"/{tasks.QUEUE}", "TextDocument:text")
    lengths = values(merged, f"/{tasks.LENGTH}", "Scalars:scalars")
    assert len(docs) == len(lengths) == rows(merged)[f"/{tasks.QUEUE}"]
    assert max(lengths) == 2.0 and lengths[-1] == 0.0 and docs[-1] == "*empty*"
    assert any(
        d.splitlines()[2].startswith("| cmd-cup |")
        and d.splitlines()[2].endswith("| running |")
        and d.splitlines()[3].startswith("| cmd-pour |")
        and d.splitlines()[3].endswith("| preempted |")
        for d in docs
        if len(d.splitlines()) == 4
    ), docs
