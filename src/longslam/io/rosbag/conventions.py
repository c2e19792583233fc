"""What a longslam bag holds, in one place: topics, frame names, encodings, the clock offset, the
ROS 2 distributions a bag is written for, and the odometry covariance a sequence's noise level implies.

Frames (REP 105 / REP 103): `odom` -> `base_link` (the robot on the floor, x forward, z up) ->
`camera_link` (the camera's body, x forward, z up, at the camera's height) -> the optical frame
(OpenCV: x right, y down, z forward; named by the topic preset). The odometry's `odom` frame is
longslam's world frame, in which the odometry starts at the true first pose. Ground truth is on
/tf as `map` -> `gt_base_link` (the true pose of base_link), so it joins the TF tree where a SLAM
system joins it: the SLAM publishes `map` -> `odom`, and at the start map, odom and the world
coincide. It is also on /groundtruth (nav_msgs/Odometry, `map` -> `base_link`) for tools that
read a pose topic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.errors import InputError


@dataclass(frozen=True)
class TopicPreset:
    """The camera's topic names and optical frame as a driver or a SLAM system's launch file
    names them, so a bag plays into it without remapping."""

    rgb: str
    depth: str  # registered to the colour camera: same frame and pixels
    camera_info: str
    depth_info: str
    optical_frame: str


TOPIC_PRESETS = {
    # longslam's own names
    "default": TopicPreset(
        "/camera/color/image_raw",
        "/camera/depth/image_raw",
        "/camera/color/camera_info",
        "/camera/depth/camera_info",
        "camera_color_optical_frame",
    ),
    # RTAB-Map's rgbd_mapping launch files (rgb_topic, depth_topic, camera_info_topic defaults)
    "rtabmap": TopicPreset(
        "/camera/rgb/image_rect_color",
        "/camera/depth_registered/image_raw",
        "/camera/rgb/camera_info",
        "/camera/depth_registered/camera_info",
        "camera_rgb_optical_frame",
    ),
    # realsense2_camera (ROS 2 wrapper 4.x: namespace camera, node camera) with align_depth enabled
    "realsense": TopicPreset(
        "/camera/camera/color/image_raw",
        "/camera/camera/aligned_depth_to_color/image_raw",
        "/camera/camera/color/camera_info",
        "/camera/camera/aligned_depth_to_color/camera_info",
        "camera_color_optical_frame",
    ),
    # openni(2)_launch with depth registration, what ORB-SLAM's ROS RGB-D nodes subscribe to
    "openni": TopicPreset(
        "/camera/rgb/image_raw",
        "/camera/depth_registered/image_raw",
        "/camera/rgb/camera_info",
        "/camera/depth_registered/camera_info",
        "camera_rgb_optical_frame",
    ),
}
DEFAULT_TOPICS = "default"

ODOM_TOPIC = "/odom"
GROUND_TRUTH_TOPIC = "/groundtruth"
META_TOPIC = "/longslam/meta"  # std_msgs/String: the sequence's meta.json and the clock offset

ODOM_FRAME, BASE_FRAME, CAMERA_LINK_FRAME = "odom", "base_link", "camera_link"
MAP_FRAME, GROUND_TRUTH_FRAME = "map", "gt_base_link"

# The metadata version each distribution's rosbag2 writes (rosbag2_storage's BagMetadata) and the
# rosbags typestore of its messages. Humble's rosbag2 (0.15) writes version 5 and reads any
# version whose offered_qos_profiles is a YAML string with numeric policies (versions 4-8); it
# fails on version 9's list of QoS maps ("bad conversion", ros2/rosbag2#1895, #2013). rosbags
# writes versions 8 and 9: 8 is the newest Humble reads, and Jazzy (0.26, version 9) reads it too.
DISTROS = {"humble": 8, "jazzy": 9}
DEFAULT_DISTRO = "humble"  # plays on Humble and on Jazzy; a Jazzy bag plays on Jazzy only


IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
STRING = "std_msgs/msg/String"

# Depth on the bag: 32FC1 metres (REP 118), NaN where there is no return. It carries longslam's
# 16-bit depth (metres x 5000) without loss: every value k / 5000 comes back as k. 16UC1 is
# millimetres (0 = no return), what most drivers publish: half the size, 1 mm steps.
DEPTH_ENCODINGS = ("32FC1", "16UC1")
RGB_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8", "mono8")

# ROS time 0 means "no time yet" to a ROS 2 node on simulated time and "the latest" to a tf2
# lookup, and longslam's sequences start at t = 0; the bag's clock is shifted by this many
# seconds, and the shift is recorded on META_TOPIC so that an import takes it off again.
CLOCK_OFFSET_S = 1_000_000_000
RELATIVE_STAMPS_BELOW_S = 86_400.0  # a first stamp under a day: the sequence's clock starts near 0

# Variance written where the noise model puts no error (lateral step, height, roll, pitch, and
# everything at noise level `none`): consumers invert the covariance, so it must not be 0.
VARIANCE_FLOOR = 1e-9


def clock_offset(first_stamp: float) -> int:
    """Seconds to add to a sequence's stamps on the bag: CLOCK_OFFSET_S for stamps that start
    near 0 (longslam's), none for stamps that are already wall-clock times (a real TUM sequence)."""
    return CLOCK_OFFSET_S if first_stamp < RELATIVE_STAMPS_BELOW_S else 0


def stamp_ns(t: float, offset_s: int) -> int:
    """Sequence seconds (6 decimals on disk) -> integer ROS nanoseconds, exactly."""
    return int(round(t * 1e6)) * 1000 + offset_s * 1_000_000_000


def seconds(ns: int, offset_s: int) -> float:
    """Integer ROS nanoseconds -> sequence seconds (the inverse of `stamp_ns`)."""
    return (int(ns) - offset_s * 1_000_000_000) / 1e9


def step_covariance(linear_variance: float, yaw_variance: float) -> np.ndarray:
    """The 6x6 covariance (x, y, z, roll, pitch, yaw) of one odometry step in `base_link` at the
    step's start, as ROS lays it out (row-major in a 36-vector): forward x and yaw from the noise
    model (`BiasNoise.step_variances`), the rest at VARIANCE_FLOOR."""
    for name, value in (("linear", linear_variance), ("yaw", yaw_variance)):
        if not np.isfinite(value) or value < 0:
            raise InputError(f"odometry {name} variance must be a finite number >= 0, got {value!r}")
    diagonal = np.full(6, VARIANCE_FLOOR)
    diagonal[0] = max(linear_variance, VARIANCE_FLOOR)
    diagonal[5] = max(yaw_variance, VARIANCE_FLOOR)
    return np.diag(diagonal)
