"""A recorded bag (ROS 1 or ROS 2) as a sequence folder (`longslam import BAG --out SEQ`).

Topics come from the options, else from the bag: a longslam bag names its own on /longslam/meta;
otherwise each role takes the one topic of its message type (colour and depth images told apart
by their encoding, a CameraInfo beside the colour image preferred). Colour and depth are paired
by header stamp as TUM's associate.py pairs them; the odometry (base in odom) and the ground
truth are interpolated to the frames and carried to the camera's optical frame through the
bag's TF; depth is stored in longslam's 16-bit scale (metres x 5000).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.timestamps import associate_lists
from longslam.core.trajectory import Trajectory
from longslam.io.overwrite_policy import SEQUENCE, check_not_an_input, check_replaceable
from longslam.io.paths import check_output_folder
from longslam.io.rosbag import require_rosbags
from longslam.io.rosbag.conventions import (
    CAMERA_INFO,
    COMPRESSED_IMAGE,
    DEPTH_ENCODINGS,
    IMAGE,
    META_TOPIC,
    ODOMETRY,
    POSE_STAMPED,
    STRING,
    TF_MESSAGE,
)
from longslam.io.rosbag.messages import (
    ROS2,
    pose_matrix,
    read_depth,
    read_rgb,
    stamp_of,
    typestore_for,
)
from longslam.io.rosbag.messages import (
    field as msg_field,
)
from longslam.io.rosbag.tf import TfBuffer, interpolate_poses
from longslam.io.sequence import DEFAULT_MAX_DIFF, DEPTH_SCALE, SequenceWriter

LARGEST_DEPTH = 65535 / DEPTH_SCALE  # metres storable in a 16-bit image at longslam's scale
MAX_GAP_S = 0.5  # odometry, ground truth and moving TF links: the most time between two messages interpolated


@dataclass
class Topics:
    rgb: str | None = None
    depth: str | None = None
    camera_info: str | None = None
    odom: str | None = None
    groundtruth: str | None = None


@dataclass
class ImportSummary:
    path: Path
    frames: int
    topics: Topics
    rgb_messages: int
    depth_messages: int
    odometry: bool
    groundtruth: bool
    depth_beyond_range: int  # depth pixels beyond max_depth, stored as "no return"
    notes: list[str] = field(default_factory=list)


def _open(bag: Path) -> Any:
    from rosbags.highlevel import AnyReader, AnyReaderError

    if not bag.exists():
        raise InputError(f"bag {bag} does not exist")
    if bag.is_dir() and not (bag / "metadata.yaml").is_file():
        raise InputError(
            f"bag folder {bag} has no metadata.yaml: a ROS 2 bag is a folder holding metadata.yaml "
            f"beside its .db3 or .mcap files (`ros2 bag reindex {bag}` rebuilds a lost one); "
            "a ROS 1 bag is one .bag file"
        )
    try:
        reader = AnyReader([bag], default_typestore=typestore_for(ROS2))
        reader.open()
    except (AnyReaderError, OSError, ValueError) as err:
        raise InputError(f"bag {bag} cannot be read as a ROS 1 (.bag file) or ROS 2 (folder) bag: {err}") from None
    return reader


class _Bag:
    """The open bag: its topics by type, and messages of one topic."""

    def __init__(self, path: Path):
        self.path = path
        self.reader = _open(path)
        self.types: dict[str, str] = {}
        for c in self.reader.connections:
            self.types.setdefault(c.topic, c.msgtype)

    def close(self) -> None:
        self.reader.close()

    def listing(self) -> str:
        return "; ".join(f"{t} ({m})" for t, m in sorted(self.types.items())) or "none"

    def connections(self, topic: str) -> list[Any]:
        return [c for c in self.reader.connections if c.topic == topic]

    def messages(self, topics: list[str]) -> Any:
        conns = [c for c in self.reader.connections if c.topic in topics]
        for c, _, raw in self.reader.messages(connections=conns):
            yield c.topic, self.reader.deserialize(raw, c.msgtype)

    def first(self, topic: str) -> Any:
        for _, message in self.messages([topic]):
            return message
        return None

    def check(self, topic: str, option: str, allowed: tuple[str, ...]) -> str:
        if topic not in self.types:
            raise InputError(f"{option} {topic}: no such topic in {self.path}; its topics: {self.listing()}")
        if self.types[topic] not in allowed:
            raise InputError(f"{option} {topic} holds {self.types[topic]}; expected {' or '.join(allowed)}")
        return topic

    def one_of(self, candidates: list[str], option: str, what: str) -> str | None:
        if len(candidates) == 1:
            return candidates[0]
        if len(candidates) > 1:
            raise InputError(
                f"{self.path} has {len(candidates)} {what} topics ({', '.join(sorted(candidates))}); "
                f"choose one with {option}"
            )
        return None


def _longslam_meta(bag: _Bag) -> dict:
    if bag.types.get(META_TOPIC) != STRING:
        return {}
    message = bag.first(META_TOPIC)
    try:
        data = json.loads(message.data) if message is not None else {}
    except (TypeError, ValueError):
        raise InputError(f"{bag.path}: {META_TOPIC} does not hold JSON") from None
    return data if isinstance(data, dict) else {}


def _choose_topics(bag: _Bag, given: Topics, meta: dict, camera_given: bool = False) -> Topics:
    """Each role's topic: given, else the longslam bag's own, else the one of its type."""
    named = meta.get("topics", {}) if isinstance(meta.get("topics"), dict) else {}
    named = {role: topic for role, topic in named.items() if topic in bag.types}  # a filtered copy may lack some
    images = [t for t, m in bag.types.items() if m in (IMAGE, COMPRESSED_IMAGE)]

    def is_depth(topic: str) -> bool:
        message = bag.first(topic)
        return getattr(message, "encoding", "").upper() in DEPTH_ENCODINGS + ("MONO16",)

    kinds = {}
    if given.rgb is None or given.depth is None:
        kinds = {t: is_depth(t) for t in images if named.get("rgb") != t and named.get("depth") != t}
    rgb = (
        bag.check(given.rgb, "--rgb", (IMAGE, COMPRESSED_IMAGE))
        if given.rgb
        else named.get("rgb") or bag.one_of([t for t, d in kinds.items() if not d], "--rgb", "colour image")
    )
    depth = (
        bag.check(given.depth, "--depth", (IMAGE,))
        if given.depth
        else named.get("depth") or bag.one_of([t for t, d in kinds.items() if d], "--depth", "depth image")
    )
    if rgb is None:
        raise InputError(
            f"{bag.path} has no colour image topic (sensor_msgs/Image rgb8, bgr8... or "
            f"CompressedImage); its topics: {bag.listing()}"
        )
    if depth is None:
        raise InputError(
            f"{bag.path} has no depth image topic (sensor_msgs/Image 32FC1 or 16UC1); " f"its topics: {bag.listing()}"
        )
    if camera_given:  # --intrinsics: no CameraInfo is read
        info: str | None = None
    elif given.camera_info:
        info = bag.check(given.camera_info, "--camera-info", (CAMERA_INFO,))
    else:
        sibling = rgb.rsplit("/", 1)[0] + "/camera_info"  # image_transport's convention
        infos = [t for t, m in bag.types.items() if m == CAMERA_INFO]
        info = named.get("camera_info") or (
            sibling if sibling in infos else bag.one_of(infos, "--camera-info", "CameraInfo")
        )
    if info is None and not camera_given:
        raise InputError(
            f"{bag.path} has no sensor_msgs/CameraInfo topic for the colour camera; give one with "
            f"--camera-info, or the intrinsics with --intrinsics fx,fy,cx,cy (its topics: {bag.listing()})"
        )
    if given.odom:
        odom: str | None = bag.check(given.odom, "--odom", (ODOMETRY,))
    elif named:  # a longslam bag says whether it has odometry
        odom = named.get("odom")
    else:
        odom = bag.one_of([t for t, m in bag.types.items() if m == ODOMETRY], "--odom", "nav_msgs/Odometry")
    if given.groundtruth:
        groundtruth: str | None = bag.check(given.groundtruth, "--groundtruth", (ODOMETRY, POSE_STAMPED))
    else:
        groundtruth = named.get("groundtruth")  # never guessed: it would look like the odometry
    return Topics(rgb, depth, info, odom, groundtruth)


def _intrinsics(message: Any, topic: str) -> tuple[Intrinsics, list[float]]:
    k = np.asarray(msg_field(message, "k"), dtype=np.float64).reshape(-1)
    if k.size != 9 or not np.all(np.isfinite(k)) or k[0] <= 0 or k[4] <= 0:
        raise InputError(f"{topic}: CameraInfo K must hold 9 finite numbers with fx, fy > 0, got {k.tolist()}")
    if int(message.width) <= 0 or int(message.height) <= 0:
        raise InputError(
            f"{topic}: CameraInfo width and height must be positive, got {message.width} x {message.height}"
        )
    distortion = [float(d) for d in np.asarray(msg_field(message, "d"), dtype=np.float64).reshape(-1)]
    return Intrinsics(
        int(message.width), int(message.height), float(k[0]), float(k[4]), float(k[2]), float(k[5])
    ), distortion


def import_bag(
    bag: str | Path,
    out: str | Path,
    topics: Topics | None = None,
    max_diff: float = DEFAULT_MAX_DIFF,
    max_depth: float | None = None,
    groundtruth_frame: str | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
    intrinsics: str | tuple[float, float, float, float] | None = None,
) -> ImportSummary:
    """Write the bag's frames as a sequence folder at `out`. Returns what was imported.

    `intrinsics` (fx, fy, cx, cy in pixels, or their 'fx,fy,cx,cy' text) stand in for the bag's
    CameraInfo, for a bag recorded without one (the image size is the colour images')."""
    topics = topics if topics is not None else Topics()  # a fresh one: Topics is mutable
    require_rosbags()
    bag, out = Path(bag), check_output_folder(out, "sequence folder")
    # --overwrite replaces a sequence, never the bag or a folder holding it (or the user's files).
    check_not_an_input(out, {"input bag": bag}, "sequence folder")
    check_replaceable(out, SEQUENCE, overwrite)
    if not (isinstance(max_diff, (int, float)) and math.isfinite(max_diff) and max_diff > 0):
        raise InputError(f"--max-diff must be a positive number of seconds, got {max_diff!r}")
    if max_depth is not None:
        _max_depth(max_depth, {})  # before the bag's first pass, which reads every message but the images
    given_k = None
    if intrinsics is not None:  # checked before the bag is read
        from longslam.io.camera_guess import parse_intrinsics

        given_k = parse_intrinsics(intrinsics if isinstance(intrinsics, str) else ",".join(map(str, intrinsics)))
        if topics.camera_info is not None:
            raise InputError(f"--intrinsics and --camera-info {topics.camera_info} both give the camera; give one")
    reader = _Bag(bag)
    try:
        return _import(reader, out, topics, float(max_diff), max_depth, groundtruth_frame, overwrite, progress, given_k)
    finally:
        reader.close()


def _import(
    bag: _Bag,
    out: Path,
    given: Topics,
    max_diff: float,
    max_depth: float | None,
    groundtruth_frame: str | None,
    overwrite: bool,
    progress: Callable[[int, int], None] | None,
    given_k: tuple[float, float, float, float] | None = None,
) -> ImportSummary:
    meta = _longslam_meta(bag)
    chosen = _choose_topics(bag, given, meta, camera_given=given_k is not None)
    assert chosen.rgb is not None and chosen.depth is not None  # or it raised
    _check_one_role_each(chosen)
    offset_ns = int(meta.get("clock_offset_s", 0)) * 1_000_000_000
    gap_ns = int(MAX_GAP_S * 1e9)
    notes: list[str] = []

    # Pass 1: everything but the images' pixels.
    tf = TfBuffer(f"bag {bag.path}", gap_ns)
    rgb_stamps: list[int] = []
    depth_stamps: list[int] = []
    camera_frame = info = None
    odom: list[tuple[int, np.ndarray]] = []
    odom_frames: set[tuple[str, str]] = set()
    truth: list[tuple[int, np.ndarray]] = []
    truth_frames: set[tuple[str, str]] = set()
    tf_topics = [t for t, m in bag.types.items() if m == TF_MESSAGE and t.lstrip("/") in ("tf", "tf_static")]
    # No camera_info topic when --intrinsics gives the camera.
    wanted = [t for t in (chosen.rgb, chosen.depth, chosen.camera_info) if t] + tf_topics
    wanted += [t for t in (chosen.odom, chosen.groundtruth) if t]
    for topic, message in bag.messages(wanted):
        if topic == chosen.rgb:
            rgb_stamps.append(stamp_of(message))
            camera_frame = camera_frame or message.header.frame_id.lstrip("/")
        elif topic == chosen.depth:
            depth_stamps.append(stamp_of(message))
        elif topic == chosen.camera_info:
            info = info or message
        elif topic == chosen.odom:
            odom.append(
                (stamp_of(message), pose_matrix(message.pose.pose.position, message.pose.pose.orientation, topic))
            )
            odom_frames.add((message.header.frame_id.lstrip("/"), message.child_frame_id.lstrip("/")))
        elif topic == chosen.groundtruth:
            pose = message.pose.pose if hasattr(message.pose, "pose") else message.pose
            truth.append((stamp_of(message), pose_matrix(pose.position, pose.orientation, topic)))
            truth_frames.add((message.header.frame_id.lstrip("/"), getattr(message, "child_frame_id", "").lstrip("/")))
        else:
            for t in message.transforms:
                tf.add(
                    t.header.frame_id,
                    t.child_frame_id,
                    pose_matrix(t.transform.translation, t.transform.rotation, topic),
                    stamp_of(t),
                    static=topic.lstrip("/") == "tf_static",
                )
    if not rgb_stamps:
        raise InputError(f"{chosen.rgb} in {bag.path} holds no messages")
    if not depth_stamps:
        raise InputError(f"{chosen.depth} in {bag.path} holds no messages")
    assert camera_frame is not None  # set with the first colour image
    distortion: list[float]
    if given_k is not None:
        first = read_rgb(bag.first(chosen.rgb), f"{chosen.rgb} message 0")
        intrinsics, distortion = Intrinsics(first.shape[1], first.shape[0], *given_k), []
    elif info is None:
        raise InputError(f"{chosen.camera_info} in {bag.path} holds no messages")
    else:
        assert chosen.camera_info is not None  # info was read from it
        intrinsics, distortion = _intrinsics(info, chosen.camera_info)
    if any(abs(d) > 0 for d in distortion):
        notes.append(
            f"{chosen.camera_info} gives distortion {distortion}; the images are used as they are "
            f"(record rectified images, e.g. image_rect_color, for an undistorted sequence)"
        )

    # Colour and depth paired by stamp, one to one (TUM's rule).
    pairs = associate_lists(np.array(rgb_stamps) / 1e9, np.array(depth_stamps) / 1e9, max_diff)
    stamp_text: dict[int, float] = {}
    kept: list[tuple[int, int]] = []
    for i, j in pairs:  # sorted by colour stamp; a stamp the sequence cannot tell apart is dropped
        t = round((rgb_stamps[i] - offset_ns) / 1e9, 6)
        if kept and t <= stamp_text[kept[-1][0]]:
            continue
        stamp_text[i] = t
        kept.append((i, j))
    if not kept:
        raise InputError(
            f"{bag.path}: no colour image on {chosen.rgb} has a depth image on {chosen.depth} within {max_diff} s "
            f"(colour {_span(rgb_stamps)}, depth {_span(depth_stamps)}); the streams cannot be synchronised "
            f"(a larger --max-diff, or other topics)"
        )
    if len(kept) < len(rgb_stamps):
        notes.append(
            f"{len(rgb_stamps) - len(kept)} of {len(rgb_stamps)} colour images had no depth image within "
            f"{max_diff} s and were left out"
        )
    frame_ns = np.array([rgb_stamps[i] for i, _ in kept], dtype=np.int64)
    frame_t = np.array([stamp_text[i] for i, _ in kept])

    odometry = None
    if chosen.odom:
        _, base_frame = _frame_pair(chosen.odom, odom, odom_frames, bag.path)
        base_poses = interpolate_poses(
            np.array([s for s, _ in odom]), np.array([p for _, p in odom]), frame_ns, gap_ns, f"odometry {chosen.odom}"
        )
        cam = np.array(
            [base_poses[k] @ tf.lookup(base_frame, camera_frame, int(frame_ns[k])) for k in range(len(frame_ns))]
        )
        odometry = Trajectory(frame_t, cam, source=f"{chosen.odom} in {bag.path}")
    ground_truth = None
    if chosen.groundtruth:
        _, child = _frame_pair(chosen.groundtruth, truth, truth_frames, bag.path)
        body = child or groundtruth_frame or (base_frame if chosen.odom else camera_frame)
        stamps = np.array([s for s, _ in truth], dtype=np.int64)
        order = np.argsort(stamps, kind="stable")
        stamps = stamps[order]
        keep = np.r_[True, np.round((stamps[1:] - offset_ns) / 1e3) > np.round((stamps[:-1] - offset_ns) / 1e3)]
        poses = np.array([truth[k][1] for k in order])[keep]
        stamps = stamps[keep]
        cam = np.array([poses[k] @ tf.lookup(body, camera_frame, int(stamps[k])) for k in range(len(stamps))])
        ground_truth = Trajectory(
            np.round((stamps - offset_ns) / 1e9, 6), cam, source=f"{chosen.groundtruth} in {bag.path}"
        )

    limit = _max_depth(max_depth, meta)
    beyond = 0
    # Pass 2: the images, written in frame order as soon as both of a frame's images are in.
    rgb_index = {i: k for k, (i, _) in enumerate(kept)}
    depth_index = {j: k for k, (_, j) in enumerate(kept)}
    pending: dict[int, dict[str, np.ndarray]] = {}
    source_meta = meta["meta"] if isinstance(meta.get("meta"), dict) else {}
    seq_meta = {
        **source_meta,
        "imported_from": str(bag.path.resolve()),
        "import_topics": vars(chosen).copy(),
        "import_notes": notes,
    }
    next_frame = 0
    counters = {chosen.rgb: -1, chosen.depth: -1}
    with SequenceWriter(out, intrinsics, limit, seq_meta, overwrite=overwrite, max_diff=max_diff) as writer:
        for topic, message in bag.messages([chosen.rgb, chosen.depth]):
            counters[topic] += 1
            n = counters[topic]
            if topic == chosen.rgb and n in rgb_index:
                k = rgb_index[n]
                pending.setdefault(k, {})["rgb"] = _checked(
                    read_rgb(message, f"{topic} message {n}"), intrinsics, topic, n
                )
            elif topic == chosen.depth and n in depth_index:
                k = depth_index[n]
                depth = _checked(read_depth(message, f"{topic} message {n}"), intrinsics, topic, n)
                far = depth > limit
                beyond += int(far.sum())
                depth[far] = 0.0
                pending.setdefault(k, {})["depth"] = depth
            while next_frame in pending and len(pending[next_frame]) == 2:
                images = pending.pop(next_frame)
                writer.add(frame_t[next_frame], images["rgb"], images["depth"])
                next_frame += 1
                if progress is not None:
                    progress(next_frame, len(kept))
        if next_frame != len(kept):
            raise InputError(
                f"{bag.path}: the images of frame t={frame_t[next_frame]:.6f} were not found on a second "
                f"reading of the bag"
            )
        if odometry is not None:
            writer.set_odometry(odometry)
        if ground_truth is not None:
            writer.set_ground_truth(ground_truth)
    if beyond:
        notes.append(f"{beyond} depth pixels beyond {limit:.3f} m were stored as 'no return'")
    return ImportSummary(
        out,
        len(kept),
        chosen,
        len(rgb_stamps),
        len(depth_stamps),
        odometry is not None,
        ground_truth is not None,
        beyond,
        notes,
    )


def _check_one_role_each(chosen: Topics) -> None:
    """One topic in two roles would give its messages to the first role only, and the second
    would be said to hold none."""
    roles: dict[str, str] = {}
    for role in ("rgb", "depth", "camera_info", "odom", "groundtruth"):
        topic = getattr(chosen, role)
        if topic is None:
            continue
        option = "--" + role.replace("_", "-")
        if topic in roles:
            raise InputError(f"{option} {topic} is also the {roles[topic]} topic; each role needs a topic of its own")
        roles[topic] = option


def _frame_pair(topic: str, messages: list, frames: set, bag_path: Path) -> tuple[str, str]:
    """The one (parent, child) frame pair a pose topic's messages name."""
    if not messages:
        raise InputError(f"{topic} in {bag_path} holds no messages")
    pair, *more = sorted(frames)
    if more:
        raise InputError(f"{topic}: its messages name more than one frame pair: {sorted(frames)}")
    return pair


def _span(stamps: list[int]) -> str:
    return f"{len(stamps)} messages from {min(stamps) / 1e9:.6f} to {max(stamps) / 1e9:.6f} s"


def _max_depth(given: float | None, meta: dict) -> float:
    value = given if given is not None else meta.get("max_depth") or LARGEST_DEPTH
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise InputError(f"--max-depth must be a number of metres, got {value!r}") from None
    if not math.isfinite(value) or not 0 < value <= LARGEST_DEPTH:
        raise InputError(
            f"--max-depth {value}: expected metres in (0, {LARGEST_DEPTH:.3f}] (16-bit depth x {DEPTH_SCALE:g})"
        )
    return value


def _checked(image: np.ndarray, intrinsics: Intrinsics, topic: str, n: int) -> np.ndarray:
    h, w = image.shape[:2]
    if (w, h) != (intrinsics.width, intrinsics.height):
        raise InputError(
            f"{topic} message {n}: image is {w} x {h} but the CameraInfo says {intrinsics.width} x "
            f"{intrinsics.height}; the depth must be registered to the colour camera (same size and frame)"
        )
    return image
