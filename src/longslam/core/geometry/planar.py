"""Planar robot poses (x, y, yaw on the floor) and the camera mounted on the robot.

The robot drives on a floor plane; its pose is (x, y, yaw), or a 4x4 matrix with only a rotation
about z. The camera sits `camera_height` above the floor looking along the robot's heading, so a
camera pose (OpenCV frame) and a planar pose convert both ways through `CameraMount`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.geometry.se3 import invert

# Rotation taking camera-frame vectors to base-frame vectors: camera z (forward) is base x,
# camera x (right) is base -y, camera y (down) is base -z.
R_BASE_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap radians into [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def fold_quarter(angle: np.ndarray | float) -> np.ndarray | float:
    """An angle modulo 90 degrees, in [-45, 45) degrees (radians): a direction of a building's
    grid of walls, where a wall and one at right angles to it are the same."""
    quarter = 0.5 * np.pi
    return np.mod(np.asarray(angle) + 0.5 * quarter, quarter) - 0.5 * quarter


def planar_poses(xyyaw: np.ndarray, z: float = 0.0) -> np.ndarray:
    """(N, 3) array of x, y, yaw -> (N, 4, 4) poses."""
    xyyaw = np.asarray(xyyaw, dtype=np.float64)
    n = len(xyyaw)
    c, s = np.cos(xyyaw[:, 2]), np.sin(xyyaw[:, 2])
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 0], poses[:, 0, 1], poses[:, 1, 0], poses[:, 1, 1] = c, -s, s, c
    poses[:, 0, 3], poses[:, 1, 3], poses[:, 2, 3] = xyyaw[:, 0], xyyaw[:, 1], z
    return poses


def base_to_camera(camera_height: float) -> np.ndarray:
    """Pose of the camera in the robot base frame: `camera_height` above the floor, looking ahead."""
    pose = np.eye(4)
    pose[:3, :3] = R_BASE_CAMERA
    pose[2, 3] = camera_height
    return pose


def camera_poses_from_planar(xyyaw: np.ndarray, camera_height: float, floor_z: float = 0.0) -> np.ndarray:
    """(N, 3) robot x, y, yaw on the floor -> (N, 4, 4) camera-in-world poses."""
    return planar_poses(xyyaw, z=floor_z) @ base_to_camera(camera_height)


def planar_from_camera_poses(poses: np.ndarray, camera_height: float) -> np.ndarray:
    """Inverse of `camera_poses_from_planar`: (N, 4, 4) camera poses -> (N, 3) x, y, yaw."""
    base = np.asarray(poses) @ invert(base_to_camera(camera_height))
    yaw = np.arctan2(base[:, 1, 0], base[:, 0, 0])
    return np.column_stack([base[:, 0, 3], base[:, 1, 3], yaw])


def xyyaw_from_pose(pose: np.ndarray) -> np.ndarray:
    """(4, 4) or (N, 4, 4) planar pose(s) -> (3,) or (N, 3) x, y, yaw.

    Only the translation in x, y and the rotation about z are kept (tilt ignored); for camera poses use
    `planar_from_camera_poses`, which
    first removes the camera's mounting rotation.
    """
    pose = np.asarray(pose, dtype=np.float64)
    yaw = np.arctan2(pose[..., 1, 0], pose[..., 0, 0])
    return np.stack([pose[..., 0, 3], pose[..., 1, 3], yaw], axis=-1)


def pose_from_xyyaw(xyyaw: np.ndarray, z: float = 0.0) -> np.ndarray:
    """(3,) x, y, yaw -> (4, 4) pose of a frame at (x, y, z) rotated by yaw about world z (see
    `planar_poses` for many at once)."""
    x, y, yaw = (float(v) for v in np.asarray(xyyaw, dtype=np.float64).reshape(3))
    c, s = np.cos(yaw), np.sin(yaw)
    pose = np.eye(4)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[:3, 3] = (x, y, z)
    return pose


def relative_xyyaw(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose of b expressed in a's frame (a^-1 * b); works on (3,) or broadcast (N, 3) arrays."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(b[..., 2] - a[..., 2])], axis=-1)


def compose_xyyaw(a: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """a * delta: the pose reached by moving `delta` (in a's frame) from a."""
    a = np.asarray(a, dtype=np.float64)
    delta = np.asarray(delta, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * delta[..., 0] - s * delta[..., 1]
    y = a[..., 1] + s * delta[..., 0] + c * delta[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + delta[..., 2])], axis=-1)


def log_xyyaw(pose: np.ndarray) -> np.ndarray:
    """SE(2)'s logarithm of (3,) or (N, 3) poses: the tangent vector GTSAM's `Pose2.Logmap` (and
    so a Pose2 factor's residual) gives, for a whole graph's edges at once."""
    pose = np.asarray(pose, dtype=np.float64)
    w = wrap_angle(pose[..., 2])
    x, y = pose[..., 0], pose[..., 1]
    c1, s = np.cos(w) - 1.0, np.sin(w)
    small = np.abs(w) < 1e-10
    scale = np.where(small, 0.0, w / np.where(small, 1.0, c1 * c1 + s * s))
    # R(pi/2) * (R^T t - t), scaled: GTSAM's closed form.
    ux, uy = (c1 + 1.0) * x + s * y - x, -s * x + (c1 + 1.0) * y - y
    vx, vy = np.where(small, x, -scale * uy), np.where(small, y, scale * ux)
    return np.stack([vx, vy, w], axis=-1)


@dataclass(frozen=True)
class CameraMount:
    """Where the camera sits on the robot, and where the floor is in the world.

    Methods see only camera poses. The odometry starts at the true first pose on a floor at
    z = 0, so the first odometry pose's height is the camera height unless the user gives one;
    the floor is then wherever that puts it.
    """

    camera_height: float
    floor_z: float = 0.0

    @classmethod
    def from_first_pose(cls, camera_pose: np.ndarray, camera_height: float | None = None) -> "CameraMount":
        """The mount seen from the first odometry pose; `camera_height` (None: infer) overrides."""
        z = float(np.asarray(camera_pose)[2, 3])
        height = z if camera_height is None else camera_height
        return cls(float(height), z - float(height))

    @property
    def camera_in_base(self) -> np.ndarray:
        return base_to_camera(self.camera_height)

    def to_planar(self, camera_poses: np.ndarray) -> np.ndarray:
        """(N, 4, 4) camera-in-world poses -> (N, 3) robot x, y, yaw."""
        return planar_from_camera_poses(camera_poses, self.camera_height)

    def to_camera(self, xyyaw: np.ndarray) -> np.ndarray:
        """(N, 3) robot x, y, yaw -> (N, 4, 4) camera-in-world poses."""
        return camera_poses_from_planar(xyyaw, self.camera_height, self.floor_z)


class JumpFilteredOdometry:
    """Wheel odometry as planar poses, with jumps (a step no robot makes in one frame) replaced by
    no motion, so that one corrupt odometry line cannot throw the whole trajectory away.

    Feed it each frame's odometry camera pose in order; `jumps` counts the steps replaced. With
    each frame's timestamp, the limits are per frame period (the shortest interval seen so far,
    so a lost second frame does not make later gaps count too few periods): a frame that comes after
    frames were lost (a dropped burst, a bag's gap) may show the motion of all of them, which is
    not a jump.
    """

    def __init__(self, mount: CameraMount, jump_distance: float = 1.0, jump_angle: float = 0.8):
        self.mount = mount
        self.jump_distance = float(jump_distance)
        self.jump_angle = float(jump_angle)
        self.jumps = 0
        self._raw_previous: np.ndarray | None = None
        self._pose: np.ndarray | None = None
        self._previous_time: float | None = None
        self._period: float | None = None  # the shortest interval between frames: one frame's time

    def _frames_elapsed(self, timestamp: float | None) -> float:
        """How many frame periods passed since the previous frame (at least 1)."""
        if timestamp is None:
            return 1.0
        previous, self._previous_time = self._previous_time, float(timestamp)
        if previous is None:
            return 1.0
        interval = float(timestamp) - previous
        if interval > 0 and (self._period is None or interval < self._period):
            self._period = interval
        return max(1.0, interval / self._period) if self._period else 1.0

    def update(self, camera_pose: np.ndarray, timestamp: float | None = None) -> np.ndarray:
        """The filtered planar pose (x, y, yaw) for the next frame's odometry camera pose, taken
        at `timestamp` (seconds; None: one frame period after the previous)."""
        raw = self.mount.to_planar(np.asarray(camera_pose)[None])[0]
        elapsed = self._frames_elapsed(timestamp)
        if self._pose is None:
            self._raw_previous, self._pose = raw, raw
            return raw
        delta = relative_xyyaw(self._raw_previous, raw)
        self._raw_previous = raw
        if np.hypot(delta[0], delta[1]) > self.jump_distance * elapsed or abs(delta[2]) > self.jump_angle * elapsed:
            self.jumps += 1
            delta = np.zeros(3)
        self._pose = compose_xyyaw(self._pose, delta)
        return self._pose
