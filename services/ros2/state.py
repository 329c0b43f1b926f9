"""The robot's state of a run (:mod:`services.ros2.recording`) as standard ROS 2 messages,
stamped with robot time (``sim_time``):

- ``/joint_states`` ``sensor_msgs/msg/JointState``: every joint's position (rad), names as in
  the MJCF (velma/control/joints.py);
- ``/tf`` ``tf2_msgs/msg/TFMessage``: ``world`` → each link (MJCF body names; a finger link
  from its parent link), ``world`` → ``<side>_HandGripLink`` (the grip frame, MJCF site),
  ``world`` → ``<side>_HandGripLink_setpoint`` (commanded, while in Cartesian impedance),
  ``world`` → each object and ``world`` → ``head_camera`` (MuJoCo's camera frame: x right,
  y up, looking along −z); ``/tf_static``: ``head_camera`` → ``head_camera_optical_frame``
  (REP 103 camera optical frame: z forward, x right, y down);
- ``/<side>_ft_sensor/wrench`` ``geometry_msgs/msg/WrenchStamped`` (N, N·m, frame
  ``<side>_ft_sensor``, the MJCF site);
- ``/head_camera/image_raw`` ``sensor_msgs/msg/Image`` (``rgb8``, the logged JPEG decoded)
  and ``/head_camera/camera_info`` ``sensor_msgs/msg/CameraInfo`` (no distortion).

Units SI; frames after REP 103 and REP 105 (``world`` the fixed frame).
"""

from __future__ import annotations

import io
from collections import defaultdict
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np

from services.ros2 import messages
from services.ros2.recording import PoseRow, RobotRecording, Stamp
from services.ros2.traffic import time_msg
from services.viewer.robot import FINGER_LINKS

WORLD = "world"
JOINT_STATES = "/joint_states"
TF = "/tf"
TF_STATIC = "/tf_static"
IMAGE = "/head_camera/image_raw"
CAMERA_INFO = "/head_camera/camera_info"
CAMERA_FRAME = "head_camera"
OPTICAL_FRAME = "head_camera_optical_frame"

JOINT_STATE = "sensor_msgs/msg/JointState"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
IMAGE_TYPE = "sensor_msgs/msg/Image"
CAMERA_INFO_TYPE = "sensor_msgs/msg/CameraInfo"

MAX_IMAGE_PIXELS = 4096 * 4096
"""The largest camera image decoded (a pour's frames are 320 × 240)."""


class Out(NamedTuple):
    """One message to write: ``topic``, ROS 2 ``typename``, ``log_time`` (POSIX ns, when it
    was logged), the rosbags ``message`` and its ``sequence`` number in the topic (None: in
    the order of log times)."""

    topic: str
    typename: str
    log_time: int
    message: Any
    sequence: int | None = None


def wrench_topic(side: str) -> str:
    return f"/{side}_ft_sensor/wrench"


_WORLD_CHILD: dict[tuple[str, ...], str] = {
    ("robot", "links"): "{}",
    ("robot", "grip"): "{}_HandGripLink",
    ("robot", "setpoint"): "{}_HandGripLink_setpoint",
    ("objects",): "{}",
}
"""Recording path below ``world/`` without its last part → the frame (of that last part) that
``world`` is the parent of."""


def child_frame(path: str) -> tuple[str, str] | None:
    """(parent frame, child frame) of a recording pose path below ``world/`` (None: not a
    frame of the export)."""
    *head, last = path.split("/")
    pattern = _WORLD_CHILD.get(tuple(head))
    if pattern is not None:
        return WORLD, pattern.format(last)
    if head[:2] == ["robot", "links"] and len(head) > 2:
        return _finger_frame(head[2], "/".join([*head[3:], last]))
    return None


def _finger_frame(palm: str, finger: str) -> tuple[str, str] | None:
    """(parent, child) of finger link ``finger`` (its path below the palm's, FINGER_LINKS) of
    the hand whose palm link is ``palm``: MJCF body names."""
    side = palm.split("_", 1)[0]
    by_path = {f.path: f"{side}_{f.joint.removesuffix('Joint')}Link" for f in FINGER_LINKS}
    if finger not in by_path:
        return None
    return by_path.get(finger.rpartition("/")[0], palm), by_path[finger]


def state_messages(rec: RobotRecording) -> Iterator[Out]:
    """Every message of the robot's state in ``rec``, topic by topic (each in time order)."""
    store = messages.typestore()
    yield from _joint_states(store, rec)
    yield from _transforms(store, rec)
    for side, rows in sorted(rec.ft.items()):
        for row in rows:
            yield Out(
                wrench_topic(side),
                WRENCH_STAMPED,
                row.stamp.wall,
                _wrench(store, row.stamp, side, row.values),
            )
    yield from _camera(store, rec)


def _header(store: Any, stamp: Stamp | int, frame: str) -> Any:
    ns = stamp.sim if isinstance(stamp, Stamp) else stamp
    return store.types["std_msgs/msg/Header"](stamp=time_msg(ns), frame_id=frame)


def _joint_states(store: Any, rec: RobotRecording) -> Iterator[Out]:
    cls = store.types[JOINT_STATE]
    names = list(rec.joint_names)
    empty = np.zeros(0, dtype=np.float64)
    for row in rec.joints:
        if len(row.values) != len(names):
            continue
        position = np.asarray(row.values, dtype=np.float64)
        msg = cls(
            header=_header(store, row.stamp, ""), name=names, position=position, velocity=empty, effort=empty
        )
        yield Out(JOINT_STATES, JOINT_STATE, row.stamp.wall, msg)


def _transform(store: Any, stamp: Stamp | int, parent: str, child: str, pose: PoseRow) -> Any:
    t = store.types
    return t["geometry_msgs/msg/TransformStamped"](
        header=_header(store, stamp, parent),
        child_frame_id=child,
        transform=t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](*pose.translation),
            rotation=t["geometry_msgs/msg/Quaternion"](*pose.quaternion),
        ),
    )


def _transforms(store: Any, rec: RobotRecording) -> Iterator[Out]:
    """One TFMessage per logged instant (all frames logged at it), then the static one."""
    at: defaultdict[Stamp, list[Any]] = defaultdict(list)
    for path, rows in rec.poses.items():
        frames = child_frame(path)
        if frames is None:
            continue
        for row in rows:
            at[row.stamp].append(_transform(store, row.stamp, *frames, row))
    for frame in rec.frames:
        at[frame.pose.stamp].append(_transform(store, frame.pose.stamp, WORLD, CAMERA_FRAME, frame.pose))
    cls = store.types[TF_MESSAGE]
    for stamp in sorted(at):
        yield Out(TF, TF_MESSAGE, stamp.wall, cls(transforms=at[stamp]))
    if rec.frames:
        # MuJoCo's camera frame (x right, y up, z back) → optical frame (x right, y down, z
        # forward): a half turn about x
        optical = PoseRow(Stamp(0, 0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
        first = rec.frames[0].pose.stamp
        yield Out(
            TF_STATIC,
            TF_MESSAGE,
            first.wall,
            cls(transforms=[_transform(store, 0, CAMERA_FRAME, OPTICAL_FRAME, optical)]),
        )


def _wrench(store: Any, stamp: Stamp, side: str, values: tuple[float, ...]) -> Any:
    t = store.types
    v3 = t["geometry_msgs/msg/Vector3"]
    return t[WRENCH_STAMPED](
        header=_header(store, stamp, f"{side}_ft_sensor"),
        wrench=t["geometry_msgs/msg/Wrench"](force=v3(*values[:3]), torque=v3(*values[3:6])),
    )


def _camera(store: Any, rec: RobotRecording) -> Iterator[Out]:
    if not rec.frames:
        return
    from PIL import Image as PILImage

    image_cls = store.types[IMAGE_TYPE]
    for frame in rec.frames:
        with PILImage.open(io.BytesIO(frame.data)) as im:
            if im.width * im.height > MAX_IMAGE_PIXELS:
                continue
            rgb = np.asarray(im.convert("RGB"), dtype=np.uint8)
        h, w = rgb.shape[:2]
        stamp = frame.pose.stamp
        msg = image_cls(
            header=_header(store, stamp, OPTICAL_FRAME),
            height=h,
            width=w,
            encoding="rgb8",
            is_bigendian=0,
            step=3 * w,
            data=rgb.reshape(-1),
        )
        yield Out(IMAGE, IMAGE_TYPE, stamp.wall, msg)
        if rec.intrinsics is not None:
            info = camera_info(store, _header(store, stamp, OPTICAL_FRAME), w, h, rec.intrinsics)
            yield Out(CAMERA_INFO, CAMERA_INFO_TYPE, stamp.wall, info)


def camera_info(store: Any, header: Any, w: int, h: int, k: Any) -> Any:
    """sensor_msgs/msg/CameraInfo of a ``w`` × ``h`` px image under ``header`` whose pinhole is
    ``k`` (3 × 3, px): REP 104 conventions, plumb_bob with no distortion, P = [K | 0]."""
    t = store.types
    k = np.asarray(k, dtype=np.float64).reshape(3, 3)
    p = np.hstack([k, np.zeros((3, 1))])
    roi = t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    return t[CAMERA_INFO_TYPE](
        header=header,
        height=h,
        width=w,
        distortion_model="plumb_bob",
        d=np.zeros(5, dtype=np.float64),
        k=k.reshape(-1),
        r=np.eye(3).reshape(-1),
        p=p.reshape(-1),
        binning_x=0,
        binning_y=0,
        roi=roi,
    )
