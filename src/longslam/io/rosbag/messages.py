"""The ROS messages of a longslam bag: built for ROS 1 or ROS 2 (which spell some fields
differently: CameraInfo's K/k, Header's seq) and read back from either."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from longslam.core.errors import InputError
from longslam.io.rosbag.conventions import (
    CAMERA_INFO,
    DEPTH_ENCODINGS,
    IMAGE,
    ODOMETRY,
    RGB_ENCODINGS,
    STRING,
    TF_MESSAGE,
)

ROS1, ROS2 = "ros1", "ros2"
_TF_MESSAGE_ROS1 = "geometry_msgs/TransformStamped[] transforms\n"


def typestore_for(ros: str, distro: str = "jazzy") -> Any:
    """rosbags' message definitions for ROS 1 Noetic (tf2_msgs added, which its store lacks) or
    for a ROS 2 distribution (humble or jazzy)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if ros == ROS1:
        store = get_typestore(Stores.ROS1_NOETIC)
        if TF_MESSAGE not in store.types:
            store.register(get_types_from_msg(_TF_MESSAGE_ROS1, TF_MESSAGE))
        return store
    stores = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY}
    if distro not in stores:
        raise InputError(f"--distro {distro!r}: expected one of {', '.join(stores)}")
    return get_typestore(stores[distro])


@dataclass
class MessageBuilder:
    """Messages of one ROS version, and their serialised bytes."""

    ros: str
    distro: str = "jazzy"  # ROS 2 only

    def __post_init__(self) -> None:
        self.store = typestore_for(self.ros, self.distro)
        self.types = self.store.types

    def serialize(self, message: Any, msgtype: str) -> bytes:
        if self.ros == ROS1:
            return bytes(self.store.serialize_ros1(message, msgtype))
        return bytes(self.store.serialize_cdr(message, msgtype))

    # pieces -------------------------------------------------------------------

    def header(self, ns: int, frame_id: str) -> Any:
        stamp = self.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        if self.ros == ROS1:
            return self.types["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame_id)
        return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def _pose(self, pose: np.ndarray) -> Any:
        position, orientation = self._translation_rotation(pose, "geometry_msgs/msg/Point")
        return self.types["geometry_msgs/msg/Pose"](position=position, orientation=orientation)

    def _transform(self, pose: np.ndarray) -> Any:
        translation, rotation = self._translation_rotation(pose, "geometry_msgs/msg/Vector3")
        return self.types["geometry_msgs/msg/Transform"](translation=translation, rotation=rotation)

    def _translation_rotation(self, pose: np.ndarray, vector_type: str) -> tuple[Any, Any]:
        """A 4x4 pose's translation as `vector_type` (a Pose holds a Point, a Transform a Vector3)
        and its rotation as a Quaternion."""
        t = self.types
        qx, qy, qz, qw = Rotation.from_matrix(pose[:3, :3]).as_quat()
        return (
            t[vector_type](x=float(pose[0, 3]), y=float(pose[1, 3]), z=float(pose[2, 3])),
            t["geometry_msgs/msg/Quaternion"](x=float(qx), y=float(qy), z=float(qz), w=float(qw)),
        )

    def _vector3(self, v) -> Any:
        return self.types["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    # messages -----------------------------------------------------------------

    def image(self, pixels: np.ndarray, encoding: str, ns: int, frame_id: str) -> Any:
        pixels = np.ascontiguousarray(pixels)
        height, width = pixels.shape[:2]
        return self.types[IMAGE](
            header=self.header(ns, frame_id),
            height=height,
            width=width,
            encoding=encoding,
            is_bigendian=0,
            step=pixels.strides[0],
            data=pixels.reshape(-1).view(np.uint8),
        )

    def camera_info(self, intrinsics, ns: int, frame_id: str) -> Any:
        i = intrinsics
        k = np.array([i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0])
        p = np.array([i.fx, 0.0, i.cx, 0.0, 0.0, i.fy, i.cy, 0.0, 0.0, 0.0, 1.0, 0.0])
        roi = self.types["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        fields = {"d": np.zeros(5), "k": k, "r": np.eye(3).reshape(-1), "p": p}
        if self.ros == ROS1:
            fields = {name.upper(): value for name, value in fields.items()}
        return self.types[CAMERA_INFO](
            header=self.header(ns, frame_id),
            height=i.height,
            width=i.width,
            distortion_model="plumb_bob",
            binning_x=0,
            binning_y=0,
            roi=roi,
            **fields,
        )

    def odometry(
        self,
        pose: np.ndarray,
        ns: int,
        frame_id: str,
        child: str,
        pose_covariance: np.ndarray,
        linear: np.ndarray,
        angular: np.ndarray,
        twist_covariance: np.ndarray,
    ) -> Any:
        t = self.types
        return t[ODOMETRY](
            header=self.header(ns, frame_id),
            child_frame_id=child,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=self._pose(pose), covariance=pose_covariance.reshape(-1).astype(np.float64)
            ),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=self._vector3(linear), angular=self._vector3(angular)),
                covariance=twist_covariance.reshape(-1).astype(np.float64),
            ),
        )

    def tf(self, transforms: list[tuple[str, str, np.ndarray, int]]) -> Any:
        """(parent, child, child-in-parent 4x4, stamp ns) -> a TFMessage."""
        stamped = [
            self.types["geometry_msgs/msg/TransformStamped"](
                header=self.header(ns, parent), child_frame_id=child, transform=self._transform(pose)
            )
            for parent, child, pose, ns in transforms
        ]
        return self.types[TF_MESSAGE](transforms=stamped)

    def string(self, text: str) -> Any:
        return self.types[STRING](data=text)


# reading: any bag, ROS 1 or ROS 2 ---------------------------------------------------------------


def field(message: Any, name: str) -> Any:
    """A field spelt in ROS 2's lower case or ROS 1's upper case (CameraInfo's K, D...)."""
    if hasattr(message, name):
        return getattr(message, name)
    return getattr(message, name.upper())


def stamp_of(message: Any) -> int:
    """The header stamp of a message, integer nanoseconds."""
    stamp = message.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def pose_matrix(position: Any, orientation: Any, where: str) -> np.ndarray:
    """A geometry_msgs position (Point or Vector3) and Quaternion -> 4x4."""
    quat = np.array([orientation.x, orientation.y, orientation.z, orientation.w], dtype=np.float64)
    norm = np.linalg.norm(quat)
    if not np.isfinite(norm) or abs(norm - 1.0) > 1e-3:
        raise InputError(f"{where}: quaternion {quat.tolist()} is not a unit quaternion")
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_quat(quat / norm).as_matrix()
    pose[:3, 3] = (position.x, position.y, position.z)
    if not np.all(np.isfinite(pose)):
        raise InputError(f"{where}: position holds NaN or inf")
    return pose


def _pixels(message: Any, dtype: np.dtype, channels: int, where: str) -> np.ndarray:
    h, w, step = int(message.height), int(message.width), int(message.step)
    data = np.asarray(message.data, dtype=np.uint8)
    row = w * channels * np.dtype(dtype).itemsize
    if step < row or data.size < step * h:
        raise InputError(
            f"{where}: {message.encoding} image of {w} x {h} needs {row} bytes a row and "
            f"{step * h} in all, got step {step} and {data.size} bytes"
        )
    rows = data[: step * h].reshape(h, step)[:, :row]
    big = bool(message.is_bigendian)
    dt = np.dtype(dtype).newbyteorder(">" if big else "<") if np.dtype(dtype).itemsize > 1 else np.dtype(dtype)
    out = (
        np.ascontiguousarray(rows).view(dt).reshape(h, w, channels)
        if channels > 1
        else np.ascontiguousarray(rows).view(dt).reshape(h, w)
    )
    return out.astype(np.dtype(dtype).newbyteorder("="), copy=False)


def read_rgb(message: Any, where: str) -> np.ndarray:
    """sensor_msgs/Image (rgb8, bgr8, rgba8, bgra8, mono8) or CompressedImage -> (H, W, 3) uint8 RGB."""
    if not hasattr(message, "encoding"):  # CompressedImage: jpeg or png bytes
        bgr = cv2.imdecode(np.asarray(message.data, dtype=np.uint8), cv2.IMREAD_COLOR)
        if bgr is None:
            raise InputError(f"{where}: compressed image (format {message.format!r}) cannot be decoded")
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    encoding = str(message.encoding).lower()
    if encoding == "rgb8":
        return _pixels(message, np.uint8, 3, where).copy()
    if encoding == "bgr8":
        return cv2.cvtColor(_pixels(message, np.uint8, 3, where), cv2.COLOR_BGR2RGB)
    if encoding == "rgba8":
        return np.ascontiguousarray(_pixels(message, np.uint8, 4, where)[..., :3])
    if encoding == "bgra8":
        return cv2.cvtColor(_pixels(message, np.uint8, 4, where), cv2.COLOR_BGRA2RGB)
    if encoding == "mono8":
        return cv2.cvtColor(_pixels(message, np.uint8, 1, where), cv2.COLOR_GRAY2RGB)
    raise InputError(
        f"{where}: colour image encoding {message.encoding!r} is not supported; expected one of "
        f"{', '.join(RGB_ENCODINGS)} or a sensor_msgs/CompressedImage"
    )


def read_depth(message: Any, where: str) -> np.ndarray:
    """sensor_msgs/Image 32FC1 (metres) or 16UC1 (millimetres) -> (H, W) float64 metres, 0 where
    there is no return (NaN, inf, 0 or negative)."""
    encoding = str(message.encoding).upper()
    if encoding == "32FC1":
        depth = _pixels(message, np.float32, 1, where).astype(np.float64)
    elif encoding in ("16UC1", "MONO16"):
        depth = _pixels(message, np.uint16, 1, where).astype(np.float64) / 1000.0
    else:
        raise InputError(
            f"{where}: depth image encoding {message.encoding!r} is not supported; expected "
            f"{' or '.join(DEPTH_ENCODINGS)} (metres or millimetres, REP 118)"
        )
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth


def encode_depth(depth_m: np.ndarray, encoding: str) -> np.ndarray:
    """(H, W) metres (0 = no return) -> the pixels of a depth Image in `encoding`."""
    if encoding == "32FC1":
        out = depth_m.astype(np.float32)
        out[depth_m <= 0] = np.nan
        return out
    if encoding == "16UC1":
        mm = np.rint(np.asarray(depth_m, dtype=np.float64) * 1000.0)
        if mm.size and mm.max() > 65535:
            raise InputError(f"depth {mm.max() / 1000:.3f} m does not fit 16UC1 millimetres (at most 65.535 m)")
        return mm.astype(np.uint16)
    raise InputError(f"depth encoding {encoding!r}: expected one of {', '.join(DEPTH_ENCODINGS)}")
