"""What a path given as a sequence folder is instead, when it is something a user may mistake for one."""

from __future__ import annotations

from pathlib import Path

# A ROS 2 bag folder holds metadata.yaml (rosbag2's index) beside its .db3 or .mcap files.
ROS2_BAG_INDEX = "metadata.yaml"


def bag_kind(path: Path) -> str | None:
    """ "a ROS 1 bag" or "a ROS 2 bag" if `path` is one, else None (from the name and layout only)."""
    if path.is_file() and path.suffix == ".bag":
        return "a ROS 1 bag"
    if path.is_dir() and (path / ROS2_BAG_INDEX).is_file():
        return "a ROS 2 bag"
    return None


def bag_refusal(path: Path) -> str | None:
    """The error for a bag given where a sequence folder was expected, or None if it is no bag."""
    kind = bag_kind(path)
    if kind is None:
        return None
    return (
        f"{path} is {kind}, not a sequence folder: turn it into one first with "
        f"`longslam import {path} --out SEQUENCE` (see `longslam import --help` for its topics)"
    )
