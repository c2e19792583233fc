"""A trajectory from one topic of a ROS 1 or ROS 2 bag, for `longslam evaluate` (evo's `bag` /
`bag2` formats).

As evo, a pose message's header stamp is its time and its pose is taken as it is (no TF lookup):
geometry_msgs/PoseStamped, PoseWithCovarianceStamped, TransformStamped and nav_msgs/Odometry. A
longslam bag's clock offset (on /longslam/meta) is taken off again, so a topic of an exported
bag matches the sequence's own files.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.core.trajectory import Trajectory
from longslam.io.rosbag import require_rosbags

POSE_TYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
    "nav_msgs/msg/Odometry",
)
_META_TOPIC = "/longslam/meta"


def is_bag(path: str | Path) -> bool:
    """A ROS 1 .bag file, an .mcap file or a ROS 2 bag folder (holding metadata.yaml)."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix in (".bag", ".mcap") and path.is_file()


def _pose(message, msgtype: str, where: str) -> np.ndarray:
    from longslam.io.rosbag.messages import pose_matrix

    if msgtype.endswith("TransformStamped"):
        return pose_matrix(message.transform.translation, message.transform.rotation, where)
    pose = message.pose.pose if hasattr(message.pose, "pose") else message.pose  # Odometry, *WithCovariance
    return pose_matrix(pose.position, pose.orientation, where)


def read_bag_trajectory(
    bag: str | Path, topic: str | None, option: str, frames: dict[str, str] | None = None
) -> Trajectory:
    """The poses on `topic` of `bag` (the bag's only pose topic if None); `option` names the
    command-line option that chooses the topic, for the error messages. `frames`, if given, is
    told the frame the poses are of (an Odometry's or TransformStamped's child_frame_id), so that
    a robot's base_link scored against camera poses can be warned of."""
    require_rosbags()
    from longslam.io.rosbag.import_ import _Bag
    from longslam.io.rosbag.messages import stamp_of

    path = Path(bag)
    opened = _Bag(path)
    try:
        pose_topics = sorted(t for t, m in opened.types.items() if m in POSE_TYPES)
        if topic is None:
            if len(pose_topics) != 1:
                found = ", ".join(f"{t} ({opened.types[t]})" for t in pose_topics) or "none"
                raise InputError(f"{path} has {len(pose_topics)} pose topics ({found}); choose one with {option} TOPIC")
            topic = pose_topics[0]
        if topic not in opened.types:
            raise InputError(f"{option} {topic}: no such topic in {path}; its topics: {opened.listing()}")
        msgtype = opened.types[topic]
        if msgtype not in POSE_TYPES:
            raise InputError(f"{option} {topic} holds {msgtype}; expected one of {', '.join(POSE_TYPES)}")
        offset_ns = 0
        if opened.types.get(_META_TOPIC) == "std_msgs/msg/String":
            meta = opened.first(_META_TOPIC)
            try:
                offset_ns = int(json.loads(meta.data).get("clock_offset_s", 0)) * 1_000_000_000
            except (TypeError, ValueError, AttributeError):
                offset_ns = 0
        stamps: list[int] = []
        poses: list[np.ndarray] = []
        for _, message in opened.messages([topic]):
            child: str = getattr(message, "child_frame_id", "")
            if frames is not None and not stamps and child:
                frames["child"] = message.child_frame_id.lstrip("/")
                frames["topic"] = topic
            stamps.append(stamp_of(message) - offset_ns)
            poses.append(_pose(message, msgtype, f"{topic} in {path}"))
    finally:
        opened.close()
    if not stamps:
        raise InputError(f"{option} {topic} in {path} holds no messages")
    order = np.argsort(stamps, kind="stable")
    return Trajectory(
        np.asarray(stamps, dtype=np.float64)[order] / 1e9, np.asarray(poses)[order], source=f"{topic} in {path}"
    )
