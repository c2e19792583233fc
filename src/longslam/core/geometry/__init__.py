"""Geometry shared by every stage: SE(3) transforms, planar robot poses, rigid fits.

`from longslam.core.geometry import X` works for every public helper; the modules say where each lives:
`se3` (4x4 transforms, TUM conversion), `planar` (x, y, yaw, the camera mount, odometry with its
jump filter), `fit` (Umeyama's rigid / similarity fit), `anchor` (a system's own map frame placed
in the world, sparse poses held per frame).
"""

from longslam.core.geometry.anchor import anchor, hold_last
from longslam.core.geometry.fit import rigid_transform, rigid_transform_2d, umeyama
from longslam.core.geometry.planar import (
    R_BASE_CAMERA,
    CameraMount,
    JumpFilteredOdometry,
    base_to_camera,
    camera_poses_from_planar,
    compose_xyyaw,
    fold_quarter,
    log_xyyaw,
    planar_from_camera_poses,
    planar_poses,
    pose_from_xyyaw,
    relative_xyyaw,
    wrap_angle,
    xyyaw_from_pose,
)
from longslam.core.geometry.se3 import invert, poses_from_tum, rigidity_violation, tum_from_poses

__all__ = [
    "R_BASE_CAMERA",
    "CameraMount",
    "anchor",
    "JumpFilteredOdometry",
    "base_to_camera",
    "camera_poses_from_planar",
    "compose_xyyaw",
    "fold_quarter",
    "hold_last",
    "invert",
    "log_xyyaw",
    "planar_from_camera_poses",
    "planar_poses",
    "pose_from_xyyaw",
    "poses_from_tum",
    "relative_xyyaw",
    "rigid_transform",
    "rigid_transform_2d",
    "rigidity_violation",
    "tum_from_poses",
    "umeyama",
    "wrap_angle",
    "xyyaw_from_pose",
]
