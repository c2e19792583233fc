"""A sequence folder as a ROS 1 or ROS 2 bag (`longslam export SEQ --format ros2 --out BAG`).

Per frame: the colour image (rgb8), the depth registered to it (32FC1 metres or 16UC1 mm), a
CameraInfo for each, the wheel odometry as nav_msgs/Odometry with the per-step covariance of
the sequence's noise level, and odom -> base_link on /tf; once: base_link -> camera_link ->
the optical frame on /tf_static and the sequence's meta.json on /longslam/meta; the ground truth
as map -> gt_base_link on /tf and on /groundtruth, at its own stamps (frames in conventions.py).
Topic names follow a preset (`--topics`); a ROS 2 bag is written for one distribution's rosbag2
(`--distro`). Written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

import longslam
from longslam.core.errors import InputError
from longslam.core.geometry import base_to_camera, invert
from longslam.core.geometry.planar import xyyaw_from_pose
from longslam.core.odometry_noise import BiasNoise, get_noise, noise_of_meta
from longslam.io.atomic import atomic_path
from longslam.io.overwrite_policy import BAG, ROS1_BAG, check_not_an_input, check_replaceable, replace_guard
from longslam.io.partials import clean_stale_partials
from longslam.io.paths import check_output_folder
from longslam.io.rosbag import require_rosbags
from longslam.io.rosbag.conventions import (
    BASE_FRAME,
    CAMERA_INFO,
    CAMERA_LINK_FRAME,
    DEFAULT_DISTRO,
    DEFAULT_TOPICS,
    DEPTH_ENCODINGS,
    DISTROS,
    GROUND_TRUTH_FRAME,
    GROUND_TRUTH_TOPIC,
    IMAGE,
    MAP_FRAME,
    META_TOPIC,
    ODOM_FRAME,
    ODOM_TOPIC,
    ODOMETRY,
    STRING,
    TF_MESSAGE,
    TOPIC_PRESETS,
    TopicPreset,
    clock_offset,
    stamp_ns,
    step_covariance,
)
from longslam.io.rosbag.messages import ROS1, ROS2, MessageBuilder, encode_depth
from longslam.io.sequence import SequenceReader

FORMATS = ("ros1", "ros2")
STORAGES = ("sqlite3", "mcap")


@dataclass(frozen=True)
class ExportSummary:
    path: Path
    frames: int
    messages: int
    bytes: int
    linear_variance: float | None  # per step, m^2 (None without odometry)
    yaw_variance: float | None  # per step, rad^2
    notes: tuple[str, ...] = ()  # what reading the sequence left out (unpaired images, repeated stamps...)


def _camera_height(reader: SequenceReader, given: float | None) -> float:
    """Height of the camera above base_link: given, meta.json's camera, or the first odometry
    (or ground-truth) pose's height over the floor at z = 0 (longslam's convention)."""
    if given is not None:  # checked by export_sequence
        return float(given)
    camera = reader.meta.get("camera")
    if isinstance(camera, dict) and isinstance(camera.get("camera_height"), (int, float)):
        return float(camera["camera_height"])
    for trajectory in (reader.odometry, reader.ground_truth):
        if trajectory is not None and len(trajectory):
            return float(trajectory.poses[0][2, 3])
    return 0.0


@dataclass
class _Bag:
    """One bag being written, ROS 1 or ROS 2, behind the same three calls."""

    path: Path
    ros: str
    storage: str
    compress: bool
    distro: str = DEFAULT_DISTRO  # ROS 2 only

    def __enter__(self) -> "_Bag":
        self.builder = MessageBuilder(self.ros, self.distro)
        self.count = 0
        if self.ros == ROS1:
            from rosbags.rosbag1 import Writer

            self.writer = Writer(self.path)
            if self.compress:
                self.writer.set_compression(Writer.CompressionFormat.LZ4)
        else:
            from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer(self.path, version=DISTROS[self.distro], storage_plugin=plugin)
            if self.compress:
                # MCAP compresses its chunks (zstd), as rosbag2's mcap plugin does with a
                # compression preset, and the metadata names no compression; sqlite3 has only
                # rosbag2's per-message zstd, which the metadata names for the player to undo.
                mode = CompressionMode.STORAGE if self.storage == "mcap" else CompressionMode.MESSAGE
                self.writer.set_compression(mode, CompressionFormat.ZSTD)
        self.writer.open()
        return self

    def __exit__(self, exc_type, exc, tb) -> Literal[False]:
        if exc_type is None:
            self.writer.close()
        else:
            try:
                self.writer.close()
            except Exception:  # the bag is thrown away with its folder anyway
                pass
        return False

    def connection(self, topic: str, msgtype: str, latched: bool = False) -> Any:
        if self.ros == ROS1:
            return self.writer.add_connection(topic, msgtype, typestore=self.builder.store, latching=int(latched))
        qos = [_latched_qos()] if latched else []
        return self.writer.add_connection(topic, msgtype, typestore=self.builder.store, offered_qos_profiles=qos)

    def write(self, connection: Any, ns: int, message: Any) -> None:
        self.writer.write(connection, ns, self.builder.serialize(message, connection.msgtype))
        self.count += 1


def _latched_qos() -> Any:
    """ROS 2's /tf_static QoS (transient local, keep last 1), so a late subscriber gets it."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    never = QosTime(0, 0)
    return Qos(
        QosHistory.KEEP_LAST,
        1,
        QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL,
        never,
        never,
        QosLiveliness.AUTOMATIC,
        never,
        False,
    )


def _check_out(out: Path, fmt: str, overwrite: bool, sequence: str | Path) -> None:
    if fmt == "ros1":
        if out.suffix != ".bag":
            raise InputError(f"--out {out}: a ROS 1 bag is one file ending in .bag")
        if out.is_dir():
            raise InputError(f"--out {out} is a folder; a ROS 1 bag is one file")
    else:
        check_output_folder(out, "bag folder")
        if out.suffix == ".bag":
            raise InputError(f"--out {out}: a ROS 2 bag is a folder; a name ending in .bag is read back as ROS 1")
    if not out.absolute().parent.is_dir():
        raise InputError(f"--out {out}: the folder {out.absolute().parent} does not exist")
    # --overwrite replaces a bag, never the sequence or a folder holding it (or the user's files).
    check_not_an_input(out, {"input sequence": sequence}, "--out")
    check_replaceable(out, ROS1_BAG if fmt == "ros1" else BAG, overwrite, "--out")


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def export_sequence(
    sequence: str | Path,
    out: str | Path,
    fmt: str = "ros2",
    depth_encoding: str = "32FC1",
    storage: str = "sqlite3",
    compress: bool = False,
    odom_noise: str | None = None,
    camera_height: float | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
    distro: str | None = None,
    topics: str = DEFAULT_TOPICS,
) -> ExportSummary:
    """Write `sequence` as a bag at `out` (ros1: a .bag file; ros2: a folder, for `distro`'s
    rosbag2, DEFAULT_DISTRO if None), its camera topics named by the preset `topics`. Returns what
    was written."""
    require_rosbags()
    if fmt not in FORMATS:
        raise InputError(f"--format {fmt!r}: expected one of {', '.join(FORMATS)}")
    if distro is not None and fmt == "ros1":
        raise InputError(f"--distro {distro} applies to ROS 2 bags only (a ROS 1 bag is for Noetic)")
    distro = DEFAULT_DISTRO if distro is None else distro
    if distro not in DISTROS:
        raise InputError(f"--distro {distro!r}: expected one of {', '.join(DISTROS)}")
    if topics not in TOPIC_PRESETS:
        raise InputError(f"--topics {topics!r}: expected one of {', '.join(TOPIC_PRESETS)}")
    if depth_encoding not in DEPTH_ENCODINGS:
        raise InputError(f"--depth-encoding {depth_encoding!r}: expected one of {', '.join(DEPTH_ENCODINGS)}")
    if storage not in STORAGES:
        raise InputError(f"--storage {storage!r}: expected one of {', '.join(STORAGES)}")
    if fmt == "ros1" and storage != "sqlite3":
        raise InputError("--storage applies to ROS 2 bags only")
    if camera_height is not None and not (np.isfinite(camera_height) and camera_height >= 0):
        raise InputError(
            f"--camera-height must be a finite number of metres, 0 or more (the camera above "
            f"base_link, which is on the floor), got {camera_height}"
        )
    given_noise = get_noise(odom_noise) if odom_noise is not None else None
    out = Path(out)
    _check_out(out, fmt, overwrite, sequence)
    reader = SequenceReader(sequence)
    noise = (
        given_noise
        if given_noise is not None
        else (noise_of_meta(reader.meta, reader.path) if reader.odometry is not None else None)
    )
    height = _camera_height(reader, camera_height)
    camera_in_base = base_to_camera(height)
    base_in_camera = invert(camera_in_base)

    clean_stale_partials(out.absolute().parent)
    with atomic_path(
        out, overwrite=overwrite, may_replace=replace_guard(ROS1_BAG if fmt == "ros1" else BAG, "--out")
    ) as tmp:
        # rosbags names a ROS 2 bag's database after its folder: write it under its final name
        # inside a staging folder, then move it to the temporary name that is renamed at the end.
        staging = tmp.with_name(tmp.name + "-staging")
        staging.mkdir()
        try:
            with _Bag(staging / out.name, ROS1 if fmt == "ros1" else ROS2, storage, compress, distro) as bag:
                _write(
                    bag,
                    reader,
                    noise,
                    depth_encoding,
                    camera_in_base,
                    base_in_camera,
                    height,
                    progress,
                    TOPIC_PRESETS[topics],
                    topics,
                )
            os.rename(staging / out.name, tmp)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    linear = yaw = None
    if noise is not None and reader.odometry is not None:
        linear, yaw = noise.step_variances()
    return ExportSummary(out, len(reader), bag.count, _size(out), linear, yaw, tuple(reader.notes))


def _write(
    bag: _Bag,
    reader: SequenceReader,
    noise: BiasNoise | None,
    depth_encoding: str,
    camera_in_base: np.ndarray,
    base_in_camera: np.ndarray,
    height: float,
    progress: Callable[[int, int], None] | None,
    names: TopicPreset,
    preset: str,
) -> None:
    b = bag.builder
    optical = names.optical_frame
    # base_link -> camera_link: the camera's body, upright at its place on the robot (REP 103);
    # camera_link -> optical: the rotation alone (x right, y down, z forward).
    link_in_base = np.eye(4)
    link_in_base[:3, 3] = camera_in_base[:3, 3]
    optical_in_link = invert(link_in_base) @ camera_in_base
    first = float(reader.timestamps[0])
    if reader.ground_truth is not None and len(reader.ground_truth):
        first = min(first, float(reader.ground_truth.timestamps[0]))
    offset = clock_offset(first)
    rgb_c = bag.connection(names.rgb, IMAGE)
    depth_c = bag.connection(names.depth, IMAGE)
    info_c = bag.connection(names.camera_info, CAMERA_INFO)
    depth_info_c = bag.connection(names.depth_info, CAMERA_INFO)
    tf_c = bag.connection("/tf", TF_MESSAGE)
    static_c = bag.connection("/tf_static", TF_MESSAGE, latched=True)
    meta_c = bag.connection(META_TOPIC, STRING, latched=True)
    odom_c = bag.connection(ODOM_TOPIC, ODOMETRY) if reader.odometry is not None else None
    gt_c = bag.connection(GROUND_TRUTH_TOPIC, ODOMETRY) if reader.ground_truth is not None else None

    first_ns = stamp_ns(first, offset)
    meta = {
        "longslam_version": longslam.__version__,
        "clock_offset_s": offset,
        "meta": reader.meta,
        "max_depth": reader.max_depth,
        "camera_height": height,
        "depth_encoding": depth_encoding,
        "step_variances": None if noise is None else list(noise.step_variances()),
        "topic_preset": preset,
        **({"distro": bag.distro} if bag.ros == ROS2 else {}),
        "frames": {
            "odom": ODOM_FRAME,
            "base": BASE_FRAME,
            "camera_link": CAMERA_LINK_FRAME,
            "optical": optical,
            **({"map": MAP_FRAME, "groundtruth": GROUND_TRUTH_FRAME} if gt_c is not None else {}),
        },
        "topics": {
            "rgb": names.rgb,
            "depth": names.depth,
            "camera_info": names.camera_info,
            **({"odom": ODOM_TOPIC} if odom_c is not None else {}),
            **({"groundtruth": GROUND_TRUTH_TOPIC} if gt_c is not None else {}),
        },
    }
    bag.write(meta_c, first_ns, b.string(json.dumps(meta, sort_keys=True)))
    bag.write(
        static_c,
        first_ns,
        b.tf(
            [
                (BASE_FRAME, CAMERA_LINK_FRAME, link_in_base, first_ns),
                (CAMERA_LINK_FRAME, optical, optical_in_link, first_ns),
            ]
        ),
    )

    if noise is not None:
        pose_cov = step_covariance(*noise.step_variances())
    gt = reader.ground_truth
    gt_next = 0
    zero_cov = np.zeros((6, 6))

    def write_truth(k: int) -> None:
        assert gt is not None  # called only for the ground truth's own poses
        ns = stamp_ns(float(gt.timestamps[k]), offset)
        base = gt.poses[k] @ base_in_camera
        bag.write(gt_c, ns, b.odometry(base, ns, MAP_FRAME, BASE_FRAME, zero_cov, np.zeros(3), np.zeros(3), zero_cov))
        bag.write(tf_c, ns, b.tf([(MAP_FRAME, GROUND_TRUTH_FRAME, base, ns)]))

    frame_dt = float(np.median(np.diff(reader.timestamps))) if len(reader) > 1 else 0.1
    previous_base, previous_t = None, 0.0
    for i in range(len(reader)):
        t = float(reader.timestamps[i])
        ns = stamp_ns(t, offset)
        while gt is not None and gt_next < len(gt) and gt.timestamps[gt_next] <= t:
            write_truth(gt_next)
            gt_next += 1
        rgb = reader.read_rgb(i)
        depth = reader.read_depth(i)
        bag.write(rgb_c, ns, b.image(rgb, "rgb8", ns, optical))
        bag.write(depth_c, ns, b.image(encode_depth(depth, depth_encoding), depth_encoding, ns, optical))
        bag.write(info_c, ns, b.camera_info(reader.intrinsics, ns, optical))
        bag.write(depth_info_c, ns, b.camera_info(reader.intrinsics, ns, optical))
        if odom_c is not None:
            frame = reader.frame(i)
            base = frame.odometry @ base_in_camera
            linear, angular = np.zeros(3), np.zeros(3)
            dt = frame_dt
            if previous_base is not None:
                dt = t - previous_t
                step = xyyaw_from_pose(invert(previous_base) @ base)  # in base_link at the step's start
                linear[:2], angular[2] = step[:2] / dt, step[2] / dt
            # pose.covariance: one step's; twist.covariance: the velocity's (per step / dt^2). As
            # the bias holds for 10 s, a stretch of T s inside one period has twist variance x T^2:
            # RTAB-Map, which takes twist.covariance as a link's, gets its 1 Hz links right.
            bag.write(
                odom_c, ns, b.odometry(base, ns, ODOM_FRAME, BASE_FRAME, pose_cov, linear, angular, pose_cov / dt**2)
            )
            bag.write(tf_c, ns, b.tf([(ODOM_FRAME, BASE_FRAME, base, ns)]))
            previous_base, previous_t = base, t
        if progress is not None:
            progress(i + 1, len(reader))
    while gt is not None and gt_next < len(gt):
        write_truth(gt_next)
        gt_next += 1
