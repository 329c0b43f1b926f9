"""``roco export RUN --mcap``: a run folder as a rosbag2 folder (rosbag2 "bag format" version 9:
``metadata.yaml`` and one MCAP file, profile ``ros2``, messages in CDR, each topic's type as
``ros2msg`` schema text and its RIHS01 hash, REP 2011).

Topics: the robot's state (:mod:`services.ros2.state`) when the run kept ``recording.rrd``,
and every communicate of the traffic record on ``/roco/traffic`` as ``roco_msgs/msg/Communicate``
(:mod:`services.ros2.traffic`). Each message's log time is when it was logged (POSIX ns: the
recorder's arrival time for a communicate); header stamps are robot time. A communicate's MCAP
``sequence`` is its place in the traffic record as written (messages are stored in log-time
order, which may differ). The run's
``run.json`` travels in the MCAP file as the metadata record ``roco.run``.

CDR by rosbags (``Typestore.serialize_cdr``), the MCAP file by ``mcap`` (its ``Writer``).
``metadata.yaml`` is written as JSON, which is YAML (1.2).
"""

from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from services.recorder.record import TrafficRecord, read_payloads, read_records
from services.ros2 import messages
from services.ros2.bag import MCAP_NAME, METADATA_YAML, RUN_METADATA, TRAFFIC_TOPIC
from services.ros2.recording import RobotRecording, read_recording
from services.ros2.state import TF_STATIC, Out, state_messages
from services.ros2.traffic import to_message
from services.runtime.run_folder import RUN_INFO, TRAFFIC_JSONL
from services.viewer.recording import RECORDING_FILE as RECORDING_NAME

BAG_VERSION = 9
ROS_DISTRO = "jazzy"
MAX_TRAFFIC_BYTES = 1 << 30
"""The largest traffic record (``traffic.jsonl`` and ``traffic.msgpack``, each) exported."""


class ExportError(ValueError):
    """A run that cannot be exported (one line, naming the path)."""


@dataclass
class Exported:
    """What :func:`export_run` wrote: the bag folder ``out``, messages per topic, and notes
    (what the run lacked)."""

    out: Path
    counts: dict[str, int] = field(default_factory=dict)
    types: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def messages(self) -> int:
        return sum(self.counts.values())


def qos(topic: str) -> list[dict[str, Any]]:
    """The offered QoS profile recorded for ``topic`` (rosbag2 v9 form): reliable, keep last
    10, volatile; ``/tf_static`` transient local, keep last 1 (as tf2's static broadcaster)."""
    static = topic == TF_STATIC
    zero = {"sec": 0, "nsec": 0}
    return [
        {
            "history": "keep_last",
            "depth": 1 if static else 10,
            "reliability": "reliable",
            "durability": "transient_local" if static else "volatile",
            "deadline": zero,
            "lifespan": zero,
            "liveliness": "automatic",
            "liveliness_lease_duration": zero,
            "avoid_ros_namespace_conventions": False,
        }
    ]


def robot_time(wall_ns: np.ndarray, clock: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Robot time (ns) at wall times ``wall_ns``, interpolated between the recording's
    (wall, sim) pairs ``clock``; 0 outside them (unknown)."""
    walls, sims = clock
    if len(walls) < 2:
        return np.zeros(len(wall_ns), dtype=np.int64)
    out = np.interp(wall_ns.astype(np.float64), walls.astype(np.float64), sims.astype(np.float64))
    inside = (wall_ns >= walls[0]) & (wall_ns <= walls[-1])
    return np.where(inside, np.round(out), 0).astype(np.int64)


def _check_size(path: Path) -> None:
    if path.exists() and path.stat().st_size > MAX_TRAFFIC_BYTES:
        raise ExportError(f"{path}: larger than the {MAX_TRAFFIC_BYTES} bytes exported")


def traffic_messages(run_dir: Path, clock: tuple[np.ndarray, np.ndarray]) -> tuple[list[Out], list[str]]:
    """The traffic record of ``run_dir`` as ``/roco/traffic`` messages, and notes. Raises
    ExportError when the record is too large or does not read."""
    from services.recorder.record import TRAFFIC_RAW

    for name in (TRAFFIC_JSONL, TRAFFIC_RAW):
        _check_size(run_dir / name)
    notes: list[str] = []
    try:
        records: list[TrafficRecord] = read_records(run_dir)
    except FileNotFoundError:
        return [], [f"no {TRAFFIC_JSONL}: no traffic exported"]
    except ValueError as exc:  # msgspec.DecodeError is a ValueError
        raise ExportError(f"{run_dir / TRAFFIC_JSONL}: {exc}") from None
    payloads: dict[Any, bytes] = {}
    try:
        payloads.update(read_payloads(run_dir))
    except ValueError as exc:
        notes.append(f"{TRAFFIC_RAW} read up to a fault ({exc}): later payloads left out")
    walls = np.array([round(r.t * 1e9) for r in records], dtype=np.int64)
    stamps = robot_time(walls, clock)
    lost = 0
    out = []
    for index, (rec, wall, stamp) in enumerate(zip(records, walls.tolist(), stamps.tolist(), strict=True)):
        payload = payloads.get(rec.ref)
        lost += payload is None
        out.append(Out(TRAFFIC_TOPIC, messages.COMMUNICATE, wall, to_message(rec, payload, stamp), index))
    if lost:
        notes.append(f"{lost} communicate(s) without their payload in {TRAFFIC_RAW}: exported without")
    return out, notes


def export_run(run_dir: Path, out: Path) -> Exported:
    """Write ``run_dir`` as the rosbag2 folder ``out`` (made; it must not exist or be empty).
    Raises ExportError (one line) when the run is no run folder, its record is too large or
    corrupt, or ``out`` is taken; MissingExtra without the ros2 extra; OSError when writing
    fails."""
    run_dir, out = Path(run_dir), Path(out)
    if not (run_dir / TRAFFIC_JSONL).is_file() and not (run_dir / RUN_INFO).is_file():
        raise ExportError(f"{run_dir} is not a run folder: it holds neither {RUN_INFO} nor {TRAFFIC_JSONL}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ExportError(f"{out} exists and is not an empty folder: give another OUT")
    store = messages.typestore()
    result = Exported(out)
    recording = _recording(run_dir, result.notes)
    clock = recording.sim_clock() if recording is not None else (np.zeros(0, np.int64), np.zeros(0, np.int64))
    items: list[Out] = []
    if recording is not None:
        items.extend(state_messages(recording))
    traffic, notes = traffic_messages(run_dir, clock)
    result.notes.extend(notes)
    items.extend(traffic)
    items.sort(key=lambda o: o.log_time)
    out.mkdir(parents=True, exist_ok=True)
    run_json = (run_dir / RUN_INFO).read_text("utf-8") if (run_dir / RUN_INFO).is_file() else None
    write_bag(out, store, items, run_json, result)
    return result


def _recording(run_dir: Path, notes: list[str]) -> RobotRecording | None:
    path = run_dir / RECORDING_NAME
    if not path.exists():
        notes.append(f"no {RECORDING_NAME} (a run without recording): traffic only, no robot state")
        return None
    try:
        return read_recording(path)
    except ValueError as exc:
        raise ExportError(str(exc)) from None


def write_bag(out: Path, store: Any, items: list[Out], run_json: str | None, result: Exported) -> None:
    """Write ``items`` (in log-time order) as the MCAP file and metadata.yaml of the folder
    ``out`` (made), ``run_json`` as the metadata record :data:`RUN_METADATA`; the counts and
    types into ``result``. Raises MissingExtra without mcap, OSError when writing fails."""
    try:
        from mcap.writer import CompressionType, Writer
    except ImportError as exc:
        raise messages.MissingExtra(
            f"writing MCAP needs the ros2 extra: {messages.EXTRA_HINT} ({exc})"
        ) from None

    topics: dict[str, str] = {}
    for item in items:
        topics.setdefault(item.topic, item.typename)
    counts: Counter[str] = Counter()
    with (out / MCAP_NAME).open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="roco export (mcap, rosbags)")
        schemas: dict[str, int] = {}
        channels: dict[str, int] = {}
        for topic, typename in sorted(topics.items()):
            if typename not in schemas:
                text = messages.message_definition(typename)
                schemas[typename] = writer.register_schema(typename, "ros2msg", text.encode("utf-8"))
            channels[topic] = writer.register_channel(
                topic,
                "cdr",
                schemas[typename],
                {
                    "offered_qos_profiles": json.dumps(qos(topic)),
                    "topic_type_hash": messages.type_hash(typename),
                },
            )
        for item in items:
            data = bytes(store.serialize_cdr(item.message, item.typename, little_endian=True))
            sequence = counts[item.topic] if item.sequence is None else item.sequence
            writer.add_message(channels[item.topic], item.log_time, data, item.log_time, sequence)
            counts[item.topic] += 1
        info = _bag_info(topics, counts, items)
        writer.add_metadata("rosbag2", {"serialized_metadata": json.dumps(info), "ROS_DISTRO": ROS_DISTRO})
        if run_json is not None:
            writer.add_metadata(RUN_METADATA, {"run.json": run_json})
        writer.finish()
    tmp = out / (METADATA_YAML + ".tmp")
    tmp.write_text(json.dumps({"rosbag2_bagfile_information": info}, indent=2) + "\n", "utf-8")
    tmp.replace(out / METADATA_YAML)
    result.counts = dict(sorted(counts.items()))
    result.types = dict(sorted(topics.items()))


def _bag_info(topics: dict[str, str], counts: Counter[str], items: list[Out]) -> dict[str, Any]:
    """rosbag2's bag information (metadata.yaml, version 9) of the written file."""
    start = items[0].log_time if items else time.time_ns()
    duration = items[-1].log_time - start if items else 0
    total = sum(counts.values())
    return {
        "version": BAG_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": total,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": topic,
                    "type": typename,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": qos(topic),
                    "type_description_hash": messages.type_hash(typename),
                },
                "message_count": counts[topic],
            }
            for topic, typename in sorted(topics.items())
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [MCAP_NAME],
        "files": [
            {
                "path": MCAP_NAME,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": total,
            }
        ],
        "custom_data": {"roco": "roco export --mcap"},
        "ros_distro": ROS_DISTRO,
    }
