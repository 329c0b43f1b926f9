"""Rerun logging of a run: the recorder's traffic side and ag_ex's robot side write their
parts of one recording; the merged ``recording.rrd`` is read back and its entities counted."""

from __future__ import annotations

import collections
import math
from pathlib import Path
from typing import Any

import pytest
from rerun.chunk import RrdReader

from services.recorder.recorder import TrafficWriter
from services.runtime import keys
from services.viewer import hooks, recording, robot, traffic, view
from shared.fipa_codec import Performative, encode
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.messages import communicate
from tests.support.rerun_run import rerun_run_dir
from velma.executor.state import FT_AXES, LINK_BODIES, RobotSnapshot

RUN = "20261121-120000-test"


def synthetic_traffic() -> list[tuple[float, str, bytes]]:
    """(arrival time, key, payload): 4 on C1 (3 L_SW), 3 on C4, one malformed on C5."""
    t0 = 1_790_000_000.0
    items: list[tuple[float, str, bytes]] = []
    for i, (state, step) in enumerate(
        [(SWState.RUNNING, "fetch_jar/grasp"), (SWState.RUNNING, "fetch_jar/lift"), (SWState.SUCCEEDED, None)]
    ):
        msg = communicate(
            Performative.INFORM,
            "a_ta",
            "a_co",
            "coordinate",
            "c1",
            SWStatus(state=state, plan_id="p1", step=step),
        )
        items.append((t0 + 0.4 * i, keys.fipa_key("C1", "a_ta", "a_co"), encode(msg)))
    items.append(
        (
            t0 + 1.5,
            keys.fipa_key("C1", "a_co", "a_ta"),
            encode(communicate(Performative.CANCEL, "a_co", "a_ta", "coordinate", "c1")),
        )
    )
    for i in range(3):
        msg = communicate(Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", f"q{i}")
        items.append((t0 + 0.1 * i, keys.fipa_key("C4", "a_pl", "a_km"), encode(msg)))
    items.append((t0 + 2.0, keys.fipa_key("C5", "a_ta", "ag_ex"), b"\xffnot a communicate"))
    return items


def snapshot(t: float, right: Pose, held: str | None = None, *, cart: bool = False) -> RobotSnapshot:
    """A synthetic state; ``cart``: the right arm has a Cartesian setpoint (0.01 m above its
    grip frame)."""
    links = {
        name: Pose(position=(0.01 * i, 0.0, t), orientation=(0.0, 0.0, 0.0, 1.0))
        for i, name in enumerate(LINK_BODIES)
    }
    above = Pose(position=(right.position[0], right.position[1], right.position[2] + 0.01))
    return RobotSnapshot(
        sim_time=t,
        joints={"torso_0_joint": 0.1 * t, "right_arm_0_joint": -0.2 * t},
        grip={"right": right, "left": Pose(position=(0.3, 0.4, 1.0))},
        held={"right": held is not None, "left": False},
        held_object={"right": held, "left": None},
        links=links,
        setpoint={"right": above if cart else None, "left": None},
        ft={"right": (0.0, 0.0, -12.0 - t, 0.1, 0.2, 0.3), "left": (0.0, 0.0, -12.0, 0.0, 0.0, 0.0)},
    )


def rows(path: Path) -> collections.Counter[str]:
    """Temporal rows per entity path in ``path``."""
    counts: collections.Counter[str] = collections.Counter()
    for chunk in RrdReader(path).stream():
        if not chunk.is_static:
            counts[chunk.entity_path] += chunk.num_rows
    return counts


def values(path: Path, entity: str, column: str) -> list[Any]:
    """The values of ``column`` (e.g. ``TextLog:text``) logged at ``entity``, in wall-time
    order, one per row (a row's one-element batch unwrapped)."""
    out: list[tuple[Any, Any]] = []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        col = next((n for n in names if n.endswith(column)), None)
        if col is None:  # e.g. a Clear's chunk
            continue
        times = batch.column("wall").cast("int64").to_pylist() if "wall" in names else [None] * batch.num_rows
        out.extend(zip(times, batch.column(col).to_pylist(), strict=True))
    ordered = [v for _, v in sorted(out, key=lambda tv: (tv[0] is None, tv[0]))]
    return [v[0] if isinstance(v, list) and len(v) == 1 else v for v in ordered]


@pytest.fixture
def run_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    return rerun_run_dir(tmp_path / RUN, monkeypatch)


def record_run(run_dir: Path) -> Path:
    """Log synthetic traffic (recorder side) and robot states (ag_ex side); merge."""
    robot_side = hooks.robot_hook("ag_ex", run_dir)
    traffic_side = hooks.traffic_hook("recorder", run_dir)
    assert robot_side is not None and traffic_side is not None
    writer = TrafficWriter(run_dir)
    for t, key, payload in synthetic_traffic():
        traffic_side.communicate(writer.write(t, key, payload), payload)
    writer.close()
    grip0 = Pose(position=(0.6, 0.2, 0.9))
    robot_side.snapshot(snapshot(0.0, grip0))
    robot_side.observation(
        Observation(
            stamp=0.05,
            objects=(
                ObjectObservation(name="jar", pose=Pose(position=(0.7, 0.2, 0.85)), particles_inside=18),
                ObjectObservation(name="bowl", pose=Pose(position=(0.7, -0.2, 0.85)), particles_inside=0),
            ),
            total_particles=18,
        )
    )
    robot_side.snapshot(
        snapshot(0.1, grip0, held="jar", cart=True)
    )  # grasp: the jar is 0.1 m ahead, 0.05 m down
    robot_side.snapshot(snapshot(0.2, Pose(position=(0.6, 0.2, 1.2)), held="jar", cart=True))  # lifted 0.3 m
    robot_side.snapshot(snapshot(0.3, Pose(position=(0.6, 0.2, 1.2)), held="jar"))  # back in joint mode
    robot_side.close()
    merged = traffic_side.finish(wait=0.0)
    assert merged is not None
    return merged


def test_one_recording_per_run(run_dir: Path) -> None:
    merged = record_run(run_dir)
    assert merged == run_dir / "recording.rrd"
    (entry,) = RrdReader(merged).recordings()
    assert (entry.application_id, entry.recording_id) == ("roco", RUN)
    parts = recording.parts(run_dir)
    assert sorted(p.name.split("-")[0] for p in parts) == ["ag_ex", "recorder"]
    assert all(recording.done_marker(p).exists() for p in parts)
    assert RrdReader(merged).blueprints(), "the layout travels with the recording"


def test_traffic_entities(run_dir: Path) -> None:
    merged = record_run(run_dir)
    counts = rows(merged)
    assert counts[f"/{traffic.TRAFFIC_LOG}"] == len(synthetic_traffic())  # one text row per communicate
    assert counts[f"/{traffic.SIZE}/C1"] == 4
    assert counts[f"/{traffic.SIZE}/C4"] == 3
    assert counts[f"/{traffic.SIZE}/C5"] == 1
    assert counts[f"/{traffic.BANDWIDTH}/C4"] == 3
    assert counts[f"/{traffic.SW_STATE}"] == 3
    assert counts[f"/{traffic.STEP}"] == 2  # the step changed twice; Succeeded has none
    texts = values(merged, f"/{traffic.TRAFFIC_LOG}", "TextLog:text")
    query = next(t for t in texts if t.startswith("(query-ref"))
    assert "(agent-identifier :name a_pl)" in query and ":protocol fipa-query" in query
    assert ":conversation-id q0" in query
    assert any(t.startswith("malformed") for t in texts)
    senders = values(merged, f"/{traffic.TRAFFIC_LOG}", "sender")
    assert senders.count("a_pl") == 3
    sw = values(merged, f"/{traffic.SW_STATE}", "TextLog:text")
    assert sw[0] == "Running plan=p1 step=fetch_jar/grasp" and sw[-1].startswith("Succeeded")


def test_robot_entities(run_dir: Path) -> None:
    merged = record_run(run_dir)
    counts = rows(merged)
    assert counts[f"/{robot.GRIP}/right"] == 4
    assert counts[f"/{robot.JOINTS}"] == 4
    assert counts[f"/{robot.CONTENT}/jar"] == 1
    assert counts[f"/{robot.CONTENT}/total"] == 1
    # jar: nominal pose, observed pose, then three snapshots while held
    assert counts[f"/{robot.OBJECTS}/jar"] == 5
    assert counts[f"/{robot.OBJECTS}/bowl"] == 2
    jar = values(merged, f"/{robot.OBJECTS}/jar", "Transform3D:translation")
    assert jar[-1] == pytest.approx([0.7, 0.2, 1.15])  # moved with the grip
    joints = values(merged, f"/{robot.JOINTS}", "Scalars:scalars")
    assert len(joints[-1]) == 2


def test_links_setpoints_ft(run_dir: Path) -> None:
    merged = record_run(run_dir)
    counts = rows(merged)
    links = {e for e in counts if e.startswith(f"/{robot.LINKS}/")}
    assert links == {f"/{robot.LINKS}/{name}" for name in LINK_BODIES}
    assert all(counts[e] == 4 for e in links)  # one transform per snapshot
    palm = values(merged, f"/{robot.LINKS}/right_HandPalmLink", "Transform3D:translation")
    assert palm[-1] == pytest.approx([0.01 * LINK_BODIES.index("right_HandPalmLink"), 0.0, 0.3])
    # the shapes are static: one geometry per MJCF geom of each body
    static = {c.entity_path for c in RrdReader(merged).stream() if c.is_static}
    n_geoms = sum(len(v) for v in robot.LINK_SHAPES.values())
    assert len([e for e in static if e.startswith(f"/{robot.LINKS}/") and "/geom" in e]) == n_geoms
    assert set(robot.LINK_SHAPES) == set(LINK_BODIES)
    # the right setpoint: two transforms while commanded, then one clear; never the left
    assert counts[f"/{robot.SETPOINT}/right"] == 3
    assert f"/{robot.SETPOINT}/left" not in counts
    sp = values(merged, f"/{robot.SETPOINT}/right", "Transform3D:translation")
    assert sp[-1] == pytest.approx([0.6, 0.2, 1.21])
    assert values(merged, f"/{robot.SETPOINT}/right", "Clear:is_recursive") == [False]
    for side in ("left", "right"):
        for axis in FT_AXES:
            assert counts[f"/{robot.FT}/{side}/{axis}"] == 4
    fz = values(merged, f"/{robot.FT}/right/fz", "Scalars:scalars")
    assert fz == pytest.approx([-12.0, -12.1, -12.2, -12.3])


def test_bandwidth_window(run_dir: Path) -> None:
    rec = recording.start("recorder", run_dir=run_dir)
    assert rec is not None
    logger = traffic.TrafficLogger(rec)
    assert logger.bandwidth("C4", 10.0, 1000) == pytest.approx(8.0)
    assert logger.bandwidth("C4", 10.5, 500) == pytest.approx(12.0)
    assert logger.bandwidth("C4", 11.0, 250) == pytest.approx(6.0)  # the first left the window
    assert logger.bandwidth("C1", 11.0, 125) == pytest.approx(1.0)
    rec.close()


def test_off_by_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROCO_RERUN", raising=False)
    assert recording.start("recorder", run_dir=tmp_path) is None
    assert hooks.traffic_hook("recorder", tmp_path) is None
    assert hooks.robot_hook("ag_ex", tmp_path) is None
    monkeypatch.setenv("ROCO_RERUN", "0")
    assert hooks.traffic_hook("recorder", tmp_path) is None
    assert not (tmp_path / recording.PARTS_DIR).exists()


def test_recording_id_override(tmp_path: Path) -> None:
    assert recording.recording_id(tmp_path / "run-1", {}) == "run-1"
    assert recording.recording_id(tmp_path / "run-1", {"ROCO_RERUN_ID": "x"}) == "x"


def test_view_finds_the_recording(run_dir: Path) -> None:
    record_run(run_dir)
    assert view.recording_files(run_dir) == (run_dir / "recording.rrd",)
    (run_dir / "recording.rrd").unlink()
    assert view.recording_files(run_dir) == (run_dir / "recording.rrd",)  # merged again
    with pytest.raises(FileNotFoundError):
        view.recording_files(run_dir / "nothing.rrd")
    assert view.has_display({"WAYLAND_DISPLAY": "wayland-0"})
    assert not view.has_display({})


def test_snapshot_from_runtime() -> None:
    """The loop's snapshot carries the link poses, the wrist F/T and the Cartesian setpoints."""
    import math

    import msgspec

    from velma.executor.gather import robot_snapshot
    from velma.executor.runtime import Runtime

    rt = Runtime(seed=0, n_particles=0)
    for _ in range(20):
        rt.cycle()
    snap = robot_snapshot(rt)
    assert tuple(snap.links) == LINK_BODIES
    for pose in snap.links.values():
        assert math.fsum(c * c for c in pose.orientation) == pytest.approx(1.0, abs=1e-9)
    palm = snap.links["right_HandPalmLink"].position
    assert palm[2] > 0.5 and abs(palm[1]) < 1.0  # held out in front of the robot, off the floor
    assert snap.setpoint == {"right": None, "left": None}  # joint impedance after start
    for side in ("left", "right"):
        f = snap.ft[side]
        assert len(f) == 6
        # the sensor carries the palm and the fingers (≈ 1.2 kg): ≈ 12 N
        assert 8.0 < math.hypot(*f[:3]) < 16.0
        assert math.hypot(*f[3:]) < 2.0  # N·m
    cmd = rt.ctrl.arm["right"]
    cmd.mode, cmd.pose = "cart", rt.grip("right")
    sp = robot_snapshot(rt).setpoint["right"]
    assert sp is not None
    assert sp.position == pytest.approx(tuple(rt.grip("right").translation))
    back = msgspec.msgpack.decode(msgspec.msgpack.encode(snap), type=RobotSnapshot)
    assert back == snap


def test_agent_graph_has_every_agent_apart(run_dir: Path) -> None:
    """The graph lists every agent of the specification once, each at its own fixed place:
    no two node centres closer than the chord of the circle between neighbours."""
    merged = record_run(run_dir)
    (chunk,) = [
        c
        for c in RrdReader(merged).stream()
        if c.is_static
        and c.entity_path == f"/{traffic.GRAPH}"
        and "GraphNodes:node_ids" in c.to_record_batch().schema.names
    ]
    batch = chunk.to_record_batch()
    ids = batch.column("GraphNodes:node_ids").to_pylist()[0]
    positions = batch.column("GraphNodes:positions").to_pylist()[0]
    spec = traffic.spec_from_env()
    assert sorted(ids) == sorted({a.name for a in spec.agents} | {e for ch in spec.channels for e in ch.ends})
    assert len(positions) == len(ids)
    chord = 2 * traffic.GRAPH_RADIUS * math.sin(math.pi / len(ids))
    for i, a in enumerate(positions):
        for b in positions[i + 1 :]:
            assert math.dist(a, b) >= chord - 1e-3
