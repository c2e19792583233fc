"""ROS bags out and in: `export` and `import`."""

from __future__ import annotations

import argparse
from typing import Any

from longslam.cli.output import note


class _LazyBar:
    """A tqdm bar that appears at the first progress report, so an error found before any work
    is the only line on stderr."""

    def __init__(self, desc: str):
        self.desc = desc
        self.bar: Any = None  # a tqdm bar once the first report comes

    def update(self, done: int, total: int) -> None:
        if self.bar is None:
            from longslam.core.progress import bar

            self.bar = bar(desc=self.desc, unit="frame", leave=False)
        self.bar.total = total
        self.bar.update(done - self.bar.n)

    def __enter__(self) -> "_LazyBar":
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()


def _progress_bar(desc: str):
    """A progress bar and the (done, total) callback that moves it."""
    bar = _LazyBar(desc)
    return bar, bar.update


def cmd_export(args: argparse.Namespace) -> None:
    from longslam.io.rosbag.export import export_sequence

    bar, update = _progress_bar("export")
    with bar:
        summary = export_sequence(
            args.sequence,
            args.out,
            fmt=args.format,
            depth_encoding=args.depth_encoding,
            storage=args.storage,
            compress=args.compress,
            odom_noise=args.odom_noise,
            camera_height=args.camera_height,
            overwrite=args.overwrite,
            progress=update,
            distro=args.distro,
            topics=args.topics,
        )
    line = f"wrote {summary.path}: {summary.frames} frames, {summary.messages} messages, {summary.bytes / 1e6:.1f} MB"
    if summary.linear_variance is not None:
        line += (
            f"; odometry covariance per step: forward {summary.linear_variance:.3g} m^2, "
            f"yaw {summary.yaw_variance:.3g} rad^2"
        )
    print(line)
    for text in summary.notes:
        note(f"{args.sequence}: {text}")


def cmd_import(args: argparse.Namespace) -> None:
    from longslam.io.rosbag.import_ import Topics, import_bag

    topics = Topics(args.rgb, args.depth, args.camera_info, args.odom, args.groundtruth)
    bar, update = _progress_bar("import")
    with bar:
        summary = import_bag(
            args.bag,
            args.out,
            topics,
            max_diff=args.max_diff,
            max_depth=args.max_depth,
            groundtruth_frame=args.groundtruth_frame,
            overwrite=args.overwrite,
            progress=update,
            intrinsics=args.intrinsics,
        )
    t = summary.topics
    print(
        f"wrote sequence {summary.path}: {summary.frames} frames from {t.rgb} ({summary.rgb_messages} messages) "
        f"and {t.depth} ({summary.depth_messages}); camera from {t.camera_info or '--intrinsics'}; "
        f"odometry {'from ' + str(t.odom) if summary.odometry else 'none'}; "
        f"ground truth {'from ' + str(t.groundtruth) if summary.groundtruth else 'none'}"
    )
    for text in summary.notes:
        note(text)


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """`export` and `import`."""
    p = sub.add_parser("export", help="write a sequence as a ROS 1 or ROS 2 bag (needs longslam[ros])")
    p.add_argument("sequence", help="sequence folder (TUM RGB-D layout)")
    p.add_argument(
        "--format", default="ros2", choices=("ros1", "ros2"), help="ros2: a bag folder (default); ros1: a .bag file"
    )
    p.add_argument("--out", required=True, help="bag to write: a folder for ros2, a file ending in .bag for ros1")
    p.add_argument(
        "--depth-encoding",
        default="32FC1",
        choices=("32FC1", "16UC1"),
        help="32FC1: metres, lossless (default); 16UC1: millimetres, half the size",
    )
    p.add_argument("--storage", default="sqlite3", choices=("sqlite3", "mcap"), help="ROS 2 storage (default sqlite3)")
    p.add_argument(
        "--compress",
        action="store_true",
        help="compress: zstd chunks (ros2 mcap), zstd per message (ros2 sqlite3), lz4 chunks (ros1)",
    )
    p.add_argument(
        "--distro",
        choices=("humble", "jazzy"),
        help="the ROS 2 distribution whose rosbag2 plays the bag (default humble: Jazzy plays it too)",
    )
    p.add_argument(
        "--topics",
        default="default",
        choices=("default", "rtabmap", "realsense", "openni"),
        help="camera topic names and optical frame as that driver or SLAM system names them (default: longslam's)",
    )
    p.add_argument(
        "--odom-noise",
        metavar="LEVEL",
        help="noise level for the odometry covariance (default: the sequence's meta.json)",
    )
    p.add_argument("--camera-height", type=float, help="camera above base_link in metres (default: the sequence's)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing bag")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("import", help="turn a ROS 1 or ROS 2 bag into a sequence folder (needs longslam[ros])")
    p.add_argument("bag", help="a .bag file (ROS 1) or a bag folder (ROS 2)")
    p.add_argument("--out", required=True, help="sequence folder to write")
    p.add_argument("--rgb", metavar="TOPIC", help="colour images (sensor_msgs/Image or CompressedImage)")
    p.add_argument(
        "--depth", metavar="TOPIC", help="depth images registered to the colour camera (32FC1 m or 16UC1 mm)"
    )
    p.add_argument("--camera-info", metavar="TOPIC", help="the colour camera's sensor_msgs/CameraInfo")
    p.add_argument("--odom", metavar="TOPIC", help="wheel odometry (nav_msgs/Odometry)")
    p.add_argument(
        "--groundtruth", metavar="TOPIC", help="ground truth (nav_msgs/Odometry or geometry_msgs/PoseStamped)"
    )
    p.add_argument(
        "--groundtruth-frame",
        metavar="FRAME",
        help="the frame a PoseStamped ground truth is the pose of (default: the odometry's child frame)",
    )
    p.add_argument(
        "--max-diff", type=float, default=0.02, help="colour-depth pairing tolerance in seconds (default 0.02)"
    )
    p.add_argument(
        "--max-depth",
        type=float,
        help="depth range in metres; farther is 'no return' (default 13.107, the 16-bit limit)",
    )
    p.add_argument(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="the colour camera's intrinsics in pixels, for a bag without CameraInfo (instead of --camera-info)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing folder")
    p.set_defaults(func=cmd_import)
