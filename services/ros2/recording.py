"""The robot's state as a run's Rerun recording holds it (``recording.rrd``: what ag_ex's viewer
hook logs, services/viewer/robot.py and camera.py), read back with rerun-sdk's own chunk reader
(``rerun.chunk.RrdReader``) into plain arrays for the exporter.

Every row carries two times: ``wall`` (POSIX ns, shared with the traffic) and ``sim_time``
(ns since the simulation began). Poses are in the frame of the entity's parent: ``world`` for
links, grips, set-points, objects and the head camera; a finger link's parent link for the
fingers. Quaternions are (x, y, z, w), translations in m.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from services.viewer import camera, robot
from velma.executor.state import FT_AXES

MAX_RECORDING_BYTES = 4 << 30
"""The largest ``recording.rrd`` read (a default pour's is ≈ 7 MB)."""
MAX_ROWS = 5_000_000
"""The most rows of robot state read from one recording."""


class RecordingError(ValueError):
    """A recording that cannot be read (too large, corrupt)."""


class Stamp(NamedTuple):
    """When a row was logged: ``wall`` POSIX ns and ``sim`` ns of simulation time."""

    wall: int
    sim: int


class PoseRow(NamedTuple):
    """One logged pose: ``stamp``, ``translation`` (m) and ``quaternion`` (x, y, z, w)."""

    stamp: Stamp
    translation: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]


class ScalarRow(NamedTuple):
    """One logged row of scalars (a joint vector, one wrench axis)."""

    stamp: Stamp
    values: tuple[float, ...]


class CameraFrame(NamedTuple):
    """One head-camera frame: ``stamp``, the camera's world pose (RUB axes, MuJoCo's camera
    frame) and the image as logged (``media_type``, e.g. ``image/jpeg``, and its bytes)."""

    pose: PoseRow
    media_type: str
    data: bytes


@dataclass
class RobotRecording:
    """What the exporter takes from a recording: ``joint_names`` and ``joints`` (rad) rows;
    ``poses`` by entity path below ``world/`` (``robot/links/<body>``, ``robot/grip/<side>``,
    ``robot/setpoint/<side>``, ``objects/<name>``, finger links); ``ft`` rows by side, each
    (fx, fy, fz, tx, ty, tz) in N and N·m; the head camera's ``intrinsics`` (3×3, row-major,
    px) and ``resolution`` (width, height px) when logged, and its ``frames``."""

    joint_names: tuple[str, ...] = ()
    joints: list[ScalarRow] = field(default_factory=list)
    poses: dict[str, list[PoseRow]] = field(default_factory=dict)
    ft: dict[str, list[ScalarRow]] = field(default_factory=dict)
    intrinsics: (
        tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]] | None
    ) = None
    resolution: tuple[int, int] | None = None
    frames: list[CameraFrame] = field(default_factory=list)

    @property
    def rows(self) -> int:
        return len(self.joints) + sum(map(len, self.poses.values())) + len(self.frames)

    def sim_clock(self) -> tuple[np.ndarray, np.ndarray]:
        """(wall ns, sim ns) of the joint rows, sorted by wall time: the pairs from which the
        robot time of a wall time is interpolated."""
        pairs = sorted({(r.stamp.wall, r.stamp.sim) for r in self.joints})
        return (
            np.array([w for w, _ in pairs], dtype=np.int64),
            np.array([s for _, s in pairs], dtype=np.int64),
        )


_WORLD = "/world/"
_FT = f"/{robot.FT}/"
_JOINTS = f"/{robot.JOINTS}"
_CAMERA = f"/{camera.ENTITY}"


def read_recording(path: Path) -> RobotRecording:
    """The robot state logged in the recording ``path``. Raises FileNotFoundError when it is
    missing, RecordingError when it is larger than :data:`MAX_RECORDING_BYTES`, holds more than
    :data:`MAX_ROWS` rows or does not read (rerun-sdk's error named)."""
    size = path.stat().st_size
    if size > MAX_RECORDING_BYTES:
        raise RecordingError(f"{path}: {size} bytes, more than the {MAX_RECORDING_BYTES} read")
    out = RobotRecording()
    ft_axes: dict[str, dict[str, list[ScalarRow]]] = {}
    try:
        _read_chunks(path, out, ft_axes)
    except RecordingError:
        raise
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{path}: not a readable Rerun recording ({exc})") from None
    for side, axes in ft_axes.items():
        out.ft[side] = _wrenches(axes)
    out.joints.sort(key=lambda r: r.stamp)
    for rows in out.poses.values():
        rows.sort(key=lambda r: r.stamp)
    out.frames.sort(key=lambda f: f.pose.stamp)
    return out


def _read_chunks(path: Path, out: RobotRecording, ft_axes: dict[str, dict[str, list[ScalarRow]]]) -> None:
    """Every chunk of the robot's entities in ``path`` into ``out`` (wrench axes into
    ``ft_axes``); RecordingError past :data:`MAX_ROWS`."""
    from rerun.chunk import RrdReader

    for chunk in RrdReader(path).stream():
        entity = chunk.entity_path
        if not (entity.startswith((_WORLD, _FT)) or entity == _JOINTS):
            continue
        batch = chunk.to_record_batch()
        cols = {n: batch.column(n) for n in batch.schema.names}
        if chunk.is_static:
            _take_static(out, entity, cols)
        elif "wall" in cols and "sim_time" in cols:
            _take_rows(out, ft_axes, entity, cols)
        if out.rows > MAX_ROWS:
            raise RecordingError(f"{path}: more than {MAX_ROWS} rows of robot state")


def _take_static(out: RobotRecording, entity: str, cols: dict[str, Any]) -> None:
    """The joints' names and the camera's pinhole model (static rows)."""
    if entity == _JOINTS and "SeriesLines:names" in cols:
        out.joint_names = tuple(cols["SeriesLines:names"].to_pylist()[-1])
    elif entity == _CAMERA and "Pinhole:image_from_camera" in cols:
        flat = cols["Pinhole:image_from_camera"].to_pylist()[-1][0]
        k = np.asarray(flat, dtype=float).reshape(3, 3).T  # Rerun's Mat3x3 is column-major
        out.intrinsics = (_vec3(k[0]), _vec3(k[1]), _vec3(k[2]))
        w, h = cols["Pinhole:resolution"].to_pylist()[-1][0]
        out.resolution = (round(w), round(h))


def _take_rows(
    out: RobotRecording, ft_axes: dict[str, dict[str, list[ScalarRow]]], entity: str, cols: dict[str, Any]
) -> None:
    """One chunk's timed rows (its columns ``cols``, pyarrow arrays) into ``out``."""
    walls = cols["wall"].cast("int64").to_pylist()
    stamps = [
        Stamp(int(w), int(s)) for w, s in zip(walls, cols["sim_time"].cast("int64").to_pylist(), strict=True)
    ]
    if entity == _JOINTS:
        out.joints += _scalar_rows(stamps, cols)
    elif entity.startswith(_FT):
        side, _, axis = entity[len(_FT) :].partition("/")
        ft_axes.setdefault(side, {}).setdefault(axis, []).extend(_scalar_rows(stamps, cols))
    elif entity == _CAMERA:
        _take_frames(out, stamps, cols)
    elif "Transform3D:translation" in cols and "Transform3D:quaternion" in cols:
        poses = out.poses.setdefault(entity[len(_WORLD) :], [])
        translations = _column(cols, "Transform3D:translation")
        quaternions = _column(cols, "Transform3D:quaternion")
        poses += [
            PoseRow(t, _vec3(p[0]), _quat(q[0]))
            for t, p, q in zip(stamps, translations, quaternions, strict=True)
            if p and q
        ]


def _scalar_rows(stamps: list[Stamp], cols: dict[str, Any]) -> list[ScalarRow]:
    if "Scalars:scalars" not in cols:
        return []
    return [
        ScalarRow(t, tuple(v)) for t, v in zip(stamps, _column(cols, "Scalars:scalars"), strict=True) if v
    ]


def _take_frames(out: RobotRecording, stamps: list[Stamp], cols: dict[str, Any]) -> None:
    if "EncodedImage:blob" not in cols or "Transform3D:translation" not in cols:
        return
    blobs = _column(cols, "EncodedImage:blob")
    media = (
        _column(cols, "EncodedImage:media_type")
        if "EncodedImage:media_type" in cols
        else [None] * len(stamps)
    )
    where = _column(cols, "Transform3D:translation")
    rot = _column(cols, "Transform3D:mat3x3") if "Transform3D:mat3x3" in cols else [None] * len(stamps)
    for t, blob, kind, p, m in zip(stamps, blobs, media, where, rot, strict=True):
        if not blob or not p:
            continue
        r = np.asarray(m[0], dtype=float).reshape(3, 3).T if m else np.eye(3)
        pose = PoseRow(t, _vec3(p[0]), quaternion_xyzw(r))
        out.frames.append(CameraFrame(pose, kind[0] if kind else "image/jpeg", bytes(blob[0])))


def _column(cols: dict[str, Any], name: str) -> list[Any]:
    return list(cols[name].to_pylist())


def _vec3(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _quat(q: Any) -> tuple[float, float, float, float]:
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def quaternion_xyzw(r: np.ndarray) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of the rotation matrix ``r`` (3×3, row-major)."""
    from velma.rotations import quat_wxyz

    w, x, y, z = quat_wxyz(r)
    return (x, y, z, w)


def _wrenches(axes: dict[str, list[ScalarRow]]) -> list[ScalarRow]:
    """The six axis series of one wrist (``fx`` … ``tz``) joined into wrench rows: one per
    stamp at which all six were logged."""
    by_stamp: dict[Stamp, dict[str, float]] = {}
    for axis, rows in axes.items():
        for r in rows:
            by_stamp.setdefault(r.stamp, {})[axis] = r.values[0]
    out = []
    for stamp in sorted(by_stamp):
        values = by_stamp[stamp]
        if all(a in values for a in FT_AXES):
            out.append(ScalarRow(stamp, tuple(values[a] for a in FT_AXES)))
    return out
