"""A rosbag2 folder made by ``roco export`` read back into roco's traffic record: the records
and payloads of ``/roco/traffic`` (:func:`services.ros2.traffic.from_message`) and the run's
``run.json`` (MCAP metadata record ``roco.run``), so that ``roco spec verify`` and ``roco
report`` take such a folder as they take a run folder.

:func:`is_bag` needs nothing installed; :func:`read_bag` needs the ``ros2`` extra (mcap for the
file, rosbags for CDR) and raises MissingExtra without it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from services.recorder.record import RecordKey, TrafficRecord
from services.ros2 import messages
from services.runtime.run_folder import BAG_METADATA, RunInfo, is_bag_folder

TRAFFIC_TOPIC = "/roco/traffic"
MCAP_NAME = "run.mcap"
METADATA_YAML = BAG_METADATA
RUN_METADATA = "roco.run"
"""Name of the MCAP metadata record that holds the run's ``run.json`` (key ``run.json``)."""

MAX_BAG_BYTES = 4 << 30
"""The largest MCAP file read back."""
MISSING = (
    "a rosbag2 folder from roco export: it holds the traffic and run.json, not the run folder's "
    "presence, faults, flags, logs, ag_ex's timing and perception records"
)
"""The note of every run read from a bag: what such a folder lacks."""


class BagError(ValueError):
    """A folder that is not a readable bag of roco's traffic (one line, naming the path)."""


@dataclass
class BagTraffic:
    """The traffic record in a bag: ``records`` in the order written (the MCAP messages'
    ``sequence``), their ``payloads`` (by
    record key; a record without payload has none), ``info`` (run.json; None when the bag has
    none) and ``notes``."""

    records: list[TrafficRecord] = field(default_factory=list)
    payloads: list[tuple[RecordKey, bytes]] = field(default_factory=list)
    info: RunInfo | None = None
    notes: list[str] = field(default_factory=list)


is_bag = is_bag_folder
"""True when a path is a rosbag2 folder with an MCAP file (services/runtime/run_folder.py)."""


def mcap_file(path: Path) -> Path:
    """The one MCAP file of the bag ``path``; BagError when there is none or more than one."""
    found = sorted(path.glob("*.mcap"))
    if len(found) != 1:
        raise BagError(f"{path}: {len(found)} MCAP files; a bag of roco export holds one")
    return found[0]


def read_bag(path: Path) -> BagTraffic:
    """The traffic record of the bag ``path``. Raises BagError when its MCAP file is missing,
    too large (:data:`MAX_BAG_BYTES`) or corrupt, MissingExtra without the ros2 extra."""
    try:
        from mcap.exceptions import McapError
    except ImportError as exc:
        raise messages.MissingExtra(
            f"reading a bag needs the ros2 extra: {messages.EXTRA_HINT} ({exc})"
        ) from None
    from rosbags.serde import SerdeError

    file = mcap_file(path)
    size = file.stat().st_size
    if size > MAX_BAG_BYTES:
        raise BagError(f"{file}: {size} bytes, more than the {MAX_BAG_BYTES} read")
    out = BagTraffic(notes=[MISSING])
    try:
        _read(file, out)
    except BagError:
        raise
    except (McapError, SerdeError, OSError, ValueError, AssertionError) as exc:
        raise BagError(f"{file}: not a readable MCAP file of roco export ({exc})") from None
    if not out.records:
        out.notes.append(f"no {TRAFFIC_TOPIC} messages in the bag")
    return out


def _read(file: Path, out: BagTraffic) -> None:
    """run.json and the traffic of the MCAP ``file`` into ``out``, the records in the order
    the traffic record was written in (the messages' ``sequence``)."""
    from mcap.reader import make_reader

    from services.ros2.traffic import from_message

    store = messages.typestore()
    with file.open("rb") as stream:
        reader = make_reader(stream)
        for meta in reader.iter_metadata():
            if meta.name == RUN_METADATA and "run.json" in meta.metadata:
                out.info = _run_info(meta.metadata["run.json"], out.notes)
        found = []
        for schema, _, message in reader.iter_messages(topics=[TRAFFIC_TOPIC]):
            if schema is None or schema.name != messages.COMMUNICATE:
                raise BagError(f"{file}: {TRAFFIC_TOPIC} is not of type {messages.COMMUNICATE}")
            found.append((message.sequence, message.data))
    found.sort(key=lambda sd: sd[0])
    for _, data in found:
        rec, payload = from_message(store.deserialize_cdr(data, messages.COMMUNICATE))
        out.records.append(rec)
        if payload is not None:
            out.payloads.append((rec.ref, payload))


def _run_info(text: str, notes: list[str]) -> RunInfo | None:
    try:
        return msgspec.json.decode(text, type=RunInfo)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        notes.append(f"the bag's run.json does not read ({exc}): ignored")
        return None
