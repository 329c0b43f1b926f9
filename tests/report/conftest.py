"""A synthetic pour run folder with real encoded communicates and known times and sizes.

The run mirrors the conversations of paper §5.7 at a small scale: initial knowledge (C5,
C6), the human command (C2), plan #1 (C3 + C4, partial), its execution (C1, C5, C6) ending in
Replan, plan #2 (complete), pouring, the final observation (17 of 20 spheres in the bowl)
and the outcome (C2). Times are seconds after ``STARTED``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.recorder.record import TRAFFIC_JSONL, TRAFFIC_RAW, TrafficRecord
from services.runtime import keys
from services.runtime.protocol_state import expected_ontology
from services.runtime.run_folder import RunInfo, write_run_info
from shared.fipa_codec import Communicate, Performative, encode
from shared.fipa_codec.aid import aid
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Arm, CommandResult, Grasp, Observe, Tilt
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_hfsm import (
    Execute,
    GroundTaskNetwork,
    HierarchicalPlan,
    PlanNode,
)
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspAffordance,
    GraspQuery,
    ObjectQuery,
    ObjectUpdate,
    Subscription,
    WorldUpdate,
)
from velma.executor.timing import TimingStats
from velma.realtime import RealtimeSetup

STARTED = 1_700_000_000.0
COMMAND_TEXT = "pour the jar into the bowl"


@dataclass
class RunBuilder:
    """Collects (record, payload) pairs; ``add`` encodes a real communicate, with its language's
    ontology, on its key (services/runtime/keys.py)."""

    records: list[TrafficRecord] = field(default_factory=list)
    payloads: list[bytes] = field(default_factory=list)

    def add(
        self,
        t: float,
        channel: str,
        sender: str,
        receiver: str,
        performative: str,
        content: msgspec.Struct | None = None,
        *,
        conversation: str | None = None,
        protocol: str | None = None,
        reply_with: str | None = None,
        in_reply_to: str | None = None,
    ) -> None:
        language, body = encode_content(content) if content is not None else (None, b"")
        msg = Communicate(
            performative=Performative(performative),
            sender=aid(sender),
            receiver=(aid(receiver),),
            content=body,
            language=language,
            encoding="msgpack" if body else None,
            ontology=expected_ontology(language) if language is not None else None,
            protocol=protocol,
            conversation_id=conversation,
            reply_with=reply_with,
            in_reply_to=in_reply_to,
        )
        payload = encode(msg)
        seq = len(self.records)
        self.records.append(
            TrafficRecord(
                seq=seq,
                t=STARTED + t,
                size=len(payload),
                channel=channel,
                sender=sender,
                receivers=(receiver,),
                performative=performative,
                protocol=protocol,
                conversation_id=conversation,
                language=language,
                ontology=msg.ontology,
                key=keys.fipa_key(channel, sender, receiver),
            )
        )
        self.payloads.append(payload)

    def sizes(self) -> list[int]:
        return [r.size for r in self.records]


def write_traffic(run_dir: Path, builder: RunBuilder) -> None:
    """traffic.jsonl (one msgspec JSON record a line) and traffic.msgpack ([seq, payload]s)."""
    enc = msgspec.json.Encoder()
    (run_dir / TRAFFIC_JSONL).write_bytes(b"".join(enc.encode(r) + b"\n" for r in builder.records))
    write_raw(run_dir, [(r.seq, p) for r, p in zip(builder.records, builder.payloads, strict=True)])


def write_raw(run_dir: Path, pairs: list[tuple[int, bytes]]) -> None:
    """The raw stream as ``read_payloads`` expects it: concatenated msgpack [seq, bin]."""
    enc = msgspec.msgpack.Encoder()
    (run_dir / TRAFFIC_RAW).write_bytes(b"".join(enc.encode((s, p)) for s, p in pairs))


def _pose(x: float) -> Pose:
    return Pose((x, 0.5, 0.9))


def _plan(plan_id: str, complete: bool, km_queries: int, planning_time_s: float) -> HierarchicalPlan:
    leaf = PlanNode(name="grasp", action=Execute(Grasp(arm=Arm.LEFT)))
    return HierarchicalPlan(
        plan_id=plan_id,
        task_id="cmd-1",
        root=PlanNode(name="fetch_jar", children=(leaf,)),
        complete=complete,
        km_queries=km_queries,
        planning_time_s=planning_time_s,
    )


def pour_run() -> RunBuilder:
    """The synthetic pour run (41 communicates); see the module docstring."""
    b = RunBuilder()
    sub: dict[str, Any] = dict(conversation="sub-1", protocol="fipa-subscribe")
    # initial knowledge 1.0–3.0 s: C6 subscription, C5 observe, C6 update
    b.add(1.0, "C6", "a_km", "a_ta", "subscribe", Subscription(), **sub)
    b.add(1.1, "C6", "a_ta", "a_km", "agree", **sub)
    b.add(
        2.0,
        "C5",
        "a_ta",
        "ag_ex",
        "request",
        Observe(),
        conversation="ex-1",
        protocol="fipa-request",
        reply_with="r1",
    )
    scene = Observation(
        stamp=0.5,
        objects=(
            ObjectObservation(name="jar", pose=_pose(0.1), particles_inside=20),
            ObjectObservation(name="bowl", pose=_pose(0.3), particles_inside=0),
        ),
        total_particles=20,
    )
    b.add(
        2.5,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        scene,
        conversation="ex-1",
        protocol="fipa-request",
        in_reply_to="r1",
    )
    b.add(
        3.0,
        "C6",
        "a_ta",
        "a_km",
        "inform",
        WorldUpdate(
            stamp=0.5,
            objects=(ObjectUpdate(name="jar", pose=_pose(0.1)), ObjectUpdate(name="bowl", pose=_pose(0.3))),
        ),
        **sub,
    )
    # the command at 10.0 s
    cmd: dict[str, Any] = dict(conversation="cmd-1", protocol="fipa-request")
    b.add(
        10.0,
        "C2",
        "a_hi",
        "a_co",
        "request",
        HumanCommand(text=COMMAND_TEXT, goal=TaskAtom("pour", ("jar", "bowl"))),
        **cmd,
    )
    b.add(10.1, "C2", "a_co", "a_hi", "agree", **cmd)
    # plan #1: request 12.0, 3 queries + 3 answers on C4 (one large), plan at 17.0
    p1: dict[str, Any] = dict(conversation="plan-req-1", protocol="fipa-request")
    b.add(
        12.0,
        "C3",
        "a_co",
        "a_pl",
        "request",
        GroundTaskNetwork(task_id="cmd-1", tasks=(TaskAtom("fetch", ("jar",)),), plan_index=1),
        **p1,
    )
    q: dict[str, Any] = dict(protocol="fipa-query")
    b.add(12.5, "C4", "a_pl", "a_km", "query-ref", ObjectQuery("jar"), conversation="q1", **q)
    b.add(13.0, "C4", "a_km", "a_pl", "inform", Answer(), conversation="q1", **q)
    b.add(
        13.5, "C4", "a_pl", "a_km", "query-ref", GraspQuery(object="jar", arm="left"), conversation="q2", **q
    )
    grasps = tuple(
        GraspAffordance(name=f"g{i}", grip_in_object=_pose(i / 10), approach=(1.0, 0.0, 0.0), distance=0.1)
        for i in range(20)
    )
    b.add(14.0, "C4", "a_km", "a_pl", "inform", Answer(grasps=grasps), conversation="q2", **q)
    b.add(14.5, "C4", "a_pl", "a_km", "query-ref", ObjectQuery("bowl"), conversation="q3", **q)
    b.add(16.0, "C4", "a_km", "a_pl", "inform", Answer(), conversation="q3", **q)
    b.add(17.0, "C3", "a_pl", "a_co", "inform", _plan("plan-1", False, 3, 4.8), **p1)
    # execution of plan #1: 18.0–26.0 on C1
    x1: dict[str, Any] = dict(conversation="exec-1", protocol="coordinate")
    b.add(17.5, "C1", "a_co", "a_ta", "request", _plan("plan-1", False, 3, 4.8), **x1)
    b.add(
        18.0,
        "C1",
        "a_ta",
        "a_co",
        "inform",
        SWStatus(state=SWState.RUNNING, plan_id="plan-1", step="fetch_jar/grasp"),
        **x1,
    )
    b.add(18.1, "C1", "a_co", "a_ta", "confirm", in_reply_to="sw-18.1", **x1)
    b.add(
        19.0,
        "C5",
        "a_ta",
        "ag_ex",
        "request",
        Grasp(arm=Arm.LEFT),
        conversation="ex-2",
        protocol="fipa-request",
        reply_with="r2",
    )
    b.add(
        21.0,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        CommandResult(command="grasp", ok=True),
        conversation="ex-2",
        protocol="fipa-request",
        in_reply_to="r2",
    )
    b.add(
        22.0,
        "C6",
        "a_ta",
        "a_km",
        "inform",
        WorldUpdate(stamp=8.0, objects=(ObjectUpdate(name="jar", held_by="left"),)),
        **sub,
    )
    b.add(
        24.0,
        "C5",
        "a_ta",
        "ag_ex",
        "request",
        Observe(objects=("bowl",)),
        conversation="ex-3",
        protocol="fipa-request",
        reply_with="r3",
    )
    b.add(
        24.5,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        Observation(
            stamp=10.0,
            objects=(ObjectObservation(name="bowl", pose=_pose(0.4), particles_inside=0),),
            total_particles=20,
        ),
        conversation="ex-3",
        protocol="fipa-request",
        in_reply_to="r3",
    )
    b.add(
        25.0,
        "C6",
        "a_ta",
        "a_km",
        "inform",
        WorldUpdate(stamp=10.0, objects=(ObjectUpdate(name="bowl", pose=_pose(0.4)),)),
        **sub,
    )
    b.add(
        26.0,
        "C1",
        "a_ta",
        "a_co",
        "inform",
        SWStatus(state=SWState.REPLAN, plan_id="plan-1", reason="bowl localised"),
        **x1,
    )
    b.add(26.1, "C1", "a_co", "a_ta", "confirm", in_reply_to="sw-26.1", **x1)
    # plan #2: request 27.0, 1 query + 1 answer, plan at 29.0
    p2: dict[str, Any] = dict(conversation="plan-req-2", protocol="fipa-request")
    b.add(
        27.0,
        "C3",
        "a_co",
        "a_pl",
        "request",
        GroundTaskNetwork(task_id="cmd-1", tasks=(TaskAtom("pour", ("jar", "bowl")),), plan_index=2),
        **p2,
    )
    b.add(27.5, "C4", "a_pl", "a_km", "query-ref", ObjectQuery("bowl"), conversation="q4", **q)
    b.add(28.0, "C4", "a_km", "a_pl", "inform", Answer(), conversation="q4", **q)
    b.add(29.0, "C3", "a_pl", "a_co", "inform", _plan("plan-2", True, 1, 1.9), **p2)
    # execution of plan #2: 31.0–43.0 on C1
    x2: dict[str, Any] = dict(conversation="exec-2", protocol="coordinate")
    b.add(30.0, "C1", "a_co", "a_ta", "request", _plan("plan-2", True, 1, 1.9), **x2)
    b.add(
        31.0,
        "C1",
        "a_ta",
        "a_co",
        "inform",
        SWStatus(state=SWState.RUNNING, plan_id="plan-2", step="pour/tilt"),
        **x2,
    )
    b.add(31.1, "C1", "a_co", "a_ta", "confirm", in_reply_to="sw-31.1", **x2)
    b.add(
        32.0,
        "C5",
        "a_ta",
        "ag_ex",
        "request",
        Tilt(arm=Arm.LEFT, pivot=(0.3, 0.5, 1.0), axis=(1.0, 0.0, 0.0), angle=2.0, duration=5.0),
        conversation="ex-4",
        protocol="fipa-request",
        reply_with="r4",
    )
    b.add(
        40.0,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        CommandResult(command="tilt", ok=True),
        conversation="ex-4",
        protocol="fipa-request",
        in_reply_to="r4",
    )
    b.add(
        41.0,
        "C5",
        "a_ta",
        "ag_ex",
        "request",
        Observe(objects=("bowl",)),
        conversation="ex-5",
        protocol="fipa-request",
        reply_with="r5",
    )
    b.add(
        42.0,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        Observation(
            stamp=30.0,
            objects=(
                ObjectObservation(name="bowl", pose=_pose(0.4), particles_inside=17, particles_inferred=2),
            ),
            total_particles=20,
        ),
        conversation="ex-5",
        protocol="fipa-request",
        in_reply_to="r5",
    )
    b.add(43.0, "C1", "a_ta", "a_co", "inform", SWStatus(state=SWState.SUCCEEDED, plan_id="plan-2"), **x2)
    b.add(43.1, "C1", "a_co", "a_ta", "confirm", in_reply_to="sw-43.1", **x2)
    b.add(
        44.0,
        "C2",
        "a_co",
        "a_hi",
        "inform",
        CommandOutcome(command_id="cmd-1", succeeded=True, detail="poured 17 of 20"),
        **cmd,
    )
    return b


@pytest.fixture
def pour() -> RunBuilder:
    return pour_run()


def _run_info() -> RunInfo:
    return RunInfo(
        command=COMMAND_TEXT,
        started=STARTED,
        command_sent=STARTED + 9.9,
        ended=STARTED + 44.5,
        succeeded=True,
        detail="poured 17 of 20",
    )


CONTROL_TIMING = TimingStats(
    pacing="realtime",
    cycles=56_000,
    window=56_000,
    compute_p50_us=410.0,
    compute_p99_us=720.0,
    compute_max_us=1300.0,
    lateness_p50_us=40.0,
    lateness_p99_us=90.0,
    lateness_max_us=400.0,
    overruns=14,
    overrun_share=14 / 56_000,
    max_consecutive_overruns=2,
    sim_time=56.0,
    setup=RealtimeSetup(policy="SCHED_FIFO", priority=80, cpus=(1,), pinned=True, cpu_latency_us=0),
    control_law="compiled",
    plant="compiled",
    long_cycles=3,
    stalls=2,
    compute_max_outside_stalls_us=1100.0,
    off_cpu_max_us=950.0,
)
"""What ag_ex writes to ag_ex_timing.json (velma.executor.timing.TimingStats)."""


@pytest.fixture
def control_timing() -> TimingStats:
    """The control-loop timing every ``make_run`` folder holds (unless ``timing=False``)."""
    return CONTROL_TIMING


@pytest.fixture
def make_run(tmp_path: Path) -> Callable[..., Path]:
    """``make_run(builder, info=True, name="run")``: a run folder under ``tmp_path`` with
    ``run.json`` (unless ``info`` is False) and the builder's traffic."""

    def make(
        builder: RunBuilder, info: bool = True, name: str = "20250101-120000", timing: bool = True
    ) -> Path:
        d = tmp_path / name
        (d / "logs").mkdir(parents=True)
        if info:
            write_run_info(d, _run_info())
        if timing:
            (d / "ag_ex_timing.json").write_bytes(msgspec.json.encode(CONTROL_TIMING))
        write_traffic(d, builder)
        return d

    return make


@pytest.fixture
def run_dir(make_run: Callable[..., Path], pour: RunBuilder) -> Path:
    """A complete run folder: run.json plus the traffic of :func:`pour_run`."""
    return make_run(pour)
