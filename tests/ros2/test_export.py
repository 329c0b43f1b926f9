"""``roco export RUN --mcap``: the bag reads back with mcap (+ mcap-ros2-support), rosbags'
AnyReader and Rerun's MCAP reader; every message's CDR is what mcap-ros2-support encodes from
the schema written in the file; the traffic comes back record for record and payload for
payload; the robot state comes out in ROS 2's types with robot time as stamps."""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from services.recorder.record import read_payloads, read_records
from services.ros2 import bag, export, messages, state
from services.ros2.export import export_run, robot_time
from tests.ros2.cdr import plain
from tests.ros2.run import FOCAL, FRAMES, HEIGHT, SNAPSHOTS, T0, WIDTH, camera_frame, write_run
from tests.viewer.test_recording import synthetic_traffic

mcap_reader = pytest.importorskip("mcap.reader", reason="the ros2 extra's mcap is not installed")
mcap_decoder = pytest.importorskip(
    "mcap_ros2.decoder", reason="the ros2 extra's mcap-ros2-support is not installed"
)
dynamic = pytest.importorskip(
    "mcap_ros2._dynamic", reason="the ros2 extra's mcap-ros2-support is not installed"
)
highlevel = pytest.importorskip("rosbags.highlevel", reason="the ros2 extra's rosbags is not installed")

NS = 1_000_000_000


@pytest.fixture
def run_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    return write_run(tmp_path / "20261127-120000", monkeypatch)


@pytest.fixture
def bag_dir(run_dir: Path, tmp_path: Path) -> Path:
    export_run(run_dir, tmp_path / "bag")
    return tmp_path / "bag"


def mcap_messages(bag_dir: Path) -> list[tuple[Any, Any, Any]]:
    """(schema, channel, message) of every message in the bag's MCAP file, by ``mcap``."""
    with (bag_dir / bag.MCAP_NAME).open("rb") as f:
        return list(mcap_reader.make_reader(f).iter_messages())


def test_bag_folder_is_rosbag2_with_one_mcap(bag_dir: Path) -> None:
    assert sorted(p.name for p in bag_dir.iterdir()) == sorted([bag.MCAP_NAME, bag.METADATA_YAML])
    with (bag_dir / bag.MCAP_NAME).open("rb") as f:
        reader = mcap_reader.make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name: s.encoding for s in summary.schemas.values()}
        channels = {c.topic: c for c in summary.channels.values()}
        names = {m.name for m in reader.iter_metadata()}
    assert set(schemas.values()) == {"ros2msg"}
    assert {c.message_encoding for c in channels.values()} == {"cdr"}
    assert channels["/roco/traffic"].metadata["topic_type_hash"] == messages.type_hash(messages.COMMUNICATE)
    assert {"rosbag2", bag.RUN_METADATA} <= names


def test_reads_back_with_rosbags_anyreader(bag_dir: Path) -> None:
    counts: Counter[str] = Counter()
    with highlevel.AnyReader([bag_dir]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        digests = {c.msgtype: c.digest for c in reader.connections}
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            counts[connection.topic] += 1
    assert types == {
        "/roco/traffic": messages.COMMUNICATE,
        state.JOINT_STATES: state.JOINT_STATE,
        state.TF: state.TF_MESSAGE,
        state.TF_STATIC: state.TF_MESSAGE,
        state.wrench_topic("left"): state.WRENCH_STAMPED,
        state.wrench_topic("right"): state.WRENCH_STAMPED,
        state.IMAGE: state.IMAGE_TYPE,
        state.CAMERA_INFO: state.CAMERA_INFO_TYPE,
    }
    assert all(digests[t] == messages.type_hash(t) for t in digests)
    assert counts["/roco/traffic"] == len(synthetic_traffic())
    assert counts[state.JOINT_STATES] == len(SNAPSHOTS) == counts[state.wrench_topic("right")]
    assert counts[state.IMAGE] == len(FRAMES) == counts[state.CAMERA_INFO]
    assert counts[state.TF_STATIC] == 1


def test_every_message_is_cdr_as_mcap_ros2_encodes_it(bag_dir: Path) -> None:
    """rosbags wrote each message; mcap-ros2-support, given the schema text in the file and the
    message as rosbags reads it, makes the same bytes."""
    store: Any = messages.typestore()
    encoders: dict[str, Any] = {}
    seen: Counter[str] = Counter()
    for schema, _, message in mcap_messages(bag_dir):
        if schema.name not in encoders:
            encoders[schema.name] = dynamic.serialize_dynamic(schema.name, schema.data.decode())[schema.name]
        decoded = store.deserialize_cdr(message.data, schema.name)
        assert bytes(encoders[schema.name](plain(decoded))) == message.data, schema.name
        seen[schema.name] += 1
    assert set(seen) == {
        messages.COMMUNICATE,
        state.JOINT_STATE,
        state.TF_MESSAGE,
        state.WRENCH_STAMPED,
        state.IMAGE_TYPE,
        state.CAMERA_INFO_TYPE,
    }


def test_mcap_ros2_decoder_reads_every_message(bag_dir: Path) -> None:
    with (bag_dir / bag.MCAP_NAME).open("rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[mcap_decoder.DecoderFactory()])
        decoded = {ch.topic: m for _, ch, _, m in reader.iter_decoded_messages()}
    assert decoded[state.JOINT_STATES].name == ["torso_0_joint", "right_arm_0_joint"]
    assert decoded["/roco/traffic"].performative in {"inform", "cancel", "query-ref", "malformed"}


def test_traffic_round_trips(run_dir: Path, bag_dir: Path) -> None:
    back = bag.read_bag(bag_dir)
    assert back.records == read_records(run_dir)
    assert back.payloads == list(read_payloads(run_dir))
    assert back.info is not None and back.info.command == "pour the jar into the bowl"


def test_traffic_parameters_and_robot_time(bag_dir: Path) -> None:
    store: Any = messages.typestore()
    by_perf: defaultdict[str, list[Any]] = defaultdict(list)
    for schema, _, message in mcap_messages(bag_dir):
        if schema.name == messages.COMMUNICATE:
            m = store.deserialize_cdr(message.data, schema.name)
            by_perf[m.performative].append((message.log_time, m))
    log_time, query = by_perf["query-ref"][1]
    assert (query.sender, query.receiver, query.channel) == ("a_pl", ["a_km"], "C4")
    assert (query.protocol, query.conversation_id) == ("fipa-query", "q1")
    assert log_time == round(query.wall_time * NS) == round((T0 + 0.1) * NS)
    # 0.1 s after the first snapshot (robot time 0, wall T0; the next at T0 + 1 s, robot 0.1 s)
    assert query.stamp.sec * NS + query.stamp.nanosec == pytest.approx(0.01 * NS, abs=2)
    (_, malformed), *_ = by_perf["malformed"]
    assert bytes(malformed.payload) == b"\xffnot a communicate" and malformed.content == ""
    assert math.isnan(malformed.reply_by)
    (_, informs) = zip(*by_perf["inform"], strict=True)
    assert all(i.content.startswith("{") and i.language for i in informs)  # the term as JSON


def test_robot_state_in_ros2_types(bag_dir: Path) -> None:
    store: Any = messages.typestore()
    got: defaultdict[str, list[Any]] = defaultdict(list)
    for schema, channel, message in mcap_messages(bag_dir):
        got[channel.topic].append(store.deserialize_cdr(message.data, schema.name))
    stamps = [j.header.stamp.sec * NS + j.header.stamp.nanosec for j in got[state.JOINT_STATES]]
    assert stamps == [round(t * NS) for t in SNAPSHOTS]
    last = got[state.JOINT_STATES][-1]
    assert last.position.tolist() == pytest.approx([0.1 * 0.3, -0.2 * 0.3])
    wrench = got[state.wrench_topic("right")][-1]
    assert wrench.header.frame_id == "right_ft_sensor" and wrench.wrench.force.z == pytest.approx(-12.3)
    frames = {(t.header.frame_id, t.child_frame_id) for m in got[state.TF] for t in m.transforms}
    assert {
        ("world", "torso_base"),
        ("world", "right_HandPalmLink"),
        ("world", "right_HandGripLink"),
        ("world", "jar"),
        ("world", state.CAMERA_FRAME),
    } <= frames
    grip = [
        t
        for m in got[state.TF]
        for t in m.transforms
        if t.child_frame_id == "right_HandGripLink" and t.header.stamp.nanosec == round(0.3 * NS)
    ]
    assert grip[0].transform.translation.z == pytest.approx(1.2)
    (static,) = got[state.TF_STATIC]
    assert [(t.header.frame_id, t.child_frame_id) for t in static.transforms] == [
        (state.CAMERA_FRAME, state.OPTICAL_FRAME)
    ]


def test_camera_frames_as_image_and_camera_info(bag_dir: Path) -> None:
    store: Any = messages.typestore()
    images, infos = [], []
    for schema, _, message in mcap_messages(bag_dir):
        if schema.name == state.IMAGE_TYPE:
            images.append(store.deserialize_cdr(message.data, schema.name))
        elif schema.name == state.CAMERA_INFO_TYPE:
            infos.append(store.deserialize_cdr(message.data, schema.name))
    image = images[1]
    assert (image.width, image.height, image.encoding, image.step) == (WIDTH, HEIGHT, "rgb8", 3 * WIDTH)
    assert image.header.frame_id == state.OPTICAL_FRAME
    assert image.header.stamp.nanosec == round(FRAMES[1] * NS)
    pixels = image.data.reshape(HEIGHT, WIDTH, 3).astype(int)
    assert np.abs(pixels - camera_frame(1)).mean() < 3  # JPEG's loss only
    k = infos[0].k.reshape(3, 3)
    assert k.tolist() == [[FOCAL, 0.0, WIDTH / 2], [0.0, FOCAL, HEIGHT / 2], [0.0, 0.0, 1.0]]
    assert infos[0].p.reshape(3, 4)[:, :3].tolist() == k.tolist()


def test_rerun_reads_the_bag(bag_dir: Path) -> None:
    """A third, independent reader: rerun-sdk's MCAP loader (rerun.chunk.McapReader)."""
    chunk = pytest.importorskip("rerun.chunk", reason="rerun-sdk has no MCAP reader")
    rows: Counter[str] = Counter()
    for c in chunk.McapReader(bag_dir / bag.MCAP_NAME).stream():
        if not c.is_static:
            rows[c.entity_path] += c.num_rows
    assert rows["/roco/traffic"] == len(synthetic_traffic())
    assert rows[f"{state.JOINT_STATES}/position"] == len(SNAPSHOTS)
    assert rows[state.IMAGE] == len(FRAMES)


def test_run_without_recording_exports_traffic_only(run_dir: Path, tmp_path: Path) -> None:
    (run_dir / "recording.rrd").unlink()
    done = export_run(run_dir, tmp_path / "bag")
    assert done.counts == {"/roco/traffic": len(synthetic_traffic())}
    assert len(done.notes) == 1 and "recording.rrd" in done.notes[0]


def test_out_taken_and_not_a_run_are_refused(run_dir: Path, tmp_path: Path) -> None:
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "x").write_text("")
    with pytest.raises(export.ExportError, match="not an empty folder"):
        export_run(run_dir, tmp_path / "bag")
    with pytest.raises(export.ExportError, match="not a run folder"):
        export_run(tmp_path / "bag", tmp_path / "bag2")


def test_robot_time_is_interpolated_inside_the_recording_only() -> None:
    clock = (np.array([10, 20, 40], dtype=np.int64), np.array([0, 100, 300], dtype=np.int64))
    walls = np.array([5, 10, 15, 30, 40, 41], dtype=np.int64)
    assert robot_time(walls, clock).tolist() == [0, 0, 50, 200, 300, 0]
    assert robot_time(walls, (clock[0][:1], clock[1][:1])).tolist() == [0] * 6
