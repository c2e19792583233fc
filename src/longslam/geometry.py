"""SE(3) and planar pose helpers shared by every stage.

A pose is a 4x4 float64 matrix, camera-in-world (or base-in-world for the robot's planar pose).
World frame: z up. Camera frame: OpenCV (x right, y down, z forward).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

# Rotation taking camera-frame vectors to base-frame vectors: camera z (forward) is base x,
# camera x (right) is base -y, camera y (down) is base -z.
R_BASE_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap radians into [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def planar_pose(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """4x4 pose of a frame at (x, y, z) rotated by yaw about world z."""
    c, s = np.cos(yaw), np.sin(yaw)
    pose = np.eye(4)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[:3, 3] = (x, y, z)
    return pose


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


def invert(pose: np.ndarray) -> np.ndarray:
    """Inverse of one (4, 4) or many (N, 4, 4) rigid transforms."""
    pose = np.asarray(pose, dtype=np.float64)
    inv = np.zeros_like(pose)
    rot_t = np.swapaxes(pose[..., :3, :3], -1, -2)
    inv[..., :3, :3] = rot_t
    inv[..., :3, 3] = -np.einsum("...ij,...j->...i", rot_t, pose[..., :3, 3])
    inv[..., 3, 3] = 1.0
    return inv


def rigidity_violation(poses: np.ndarray) -> np.ndarray:
    """Per pose, how far it is from a rigid transform (0 for an exact one).

    Measures ||R^T R - I||, |det R - 1| and the bottom row, so that scaled, sheared or
    reflected matrices are caught.
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    rot = poses[:, :3, :3]
    ortho = np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3)).max(axis=(1, 2))
    det = np.abs(np.linalg.det(rot) - 1.0)
    bottom = np.abs(poses[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    return np.maximum(np.maximum(ortho, det), bottom)


def poses_from_tum(txyz_q: np.ndarray) -> np.ndarray:
    """(N, 7) tx ty tz qx qy qz qw -> (N, 4, 4) poses. Quaternions are normalised."""
    arr = np.asarray(txyz_q, dtype=np.float64).reshape(-1, 7)
    quat = arr[:, 3:7]
    norms = np.linalg.norm(quat, axis=1)
    poses = np.tile(np.eye(4), (len(arr), 1, 1))
    if len(arr):
        poses[:, :3, :3] = Rotation.from_quat(quat / norms[:, None]).as_matrix()
        poses[:, :3, 3] = arr[:, :3]
    return poses


def tum_from_poses(poses: np.ndarray) -> np.ndarray:
    """(N, 4, 4) poses -> (N, 7) tx ty tz qx qy qz qw (qw >= 0)."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    if not len(poses):
        return np.zeros((0, 7))
    quat = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    quat[quat[:, 3] < 0] *= -1.0
    return np.column_stack([poses[:, :3, 3], quat])


def rotation_angle(rotations: np.ndarray) -> np.ndarray:
    """Rotation angle in radians of (..., 3, 3) rotation matrices."""
    trace = np.trace(np.asarray(rotations), axis1=-2, axis2=-1)
    return np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))
