"""What a longslam bag holds, in one place: topics, frame names, encodings, the clock offset, and
the odometry covariance that a sequence's noise level implies.

Frames (REP 105 / REP 103): `odom` -> `base_link` (the robot on the floor, x forward, z up) ->
`camera_color_optical_frame` (OpenCV: x right, y down, z forward). The odometry's `odom` frame
is longslam's world frame, in which the odometry starts at the true first pose. Ground truth is
`world` -> `base_link` on its own topic, never on /tf (a TF tree allows one parent per frame).
"""

from __future__ import annotations

import numpy as np

from longslam.errors import InputError

RGB_TOPIC = "/camera/color/image_raw"
DEPTH_TOPIC = "/camera/depth/image_raw"  # registered to the colour camera: same frame and pixels
CAMERA_INFO_TOPIC = "/camera/color/camera_info"
DEPTH_INFO_TOPIC = "/camera/depth/camera_info"
ODOM_TOPIC = "/odom"
GROUND_TRUTH_TOPIC = "/groundtruth"
META_TOPIC = "/longslam/meta"  # std_msgs/String: the sequence's meta.json and the clock offset

ODOM_FRAME, BASE_FRAME, WORLD_FRAME = "odom", "base_link", "world"
CAMERA_FRAME = "camera_color_optical_frame"

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
