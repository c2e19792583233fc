"""SE(3) helpers: inverting, checking and converting 4x4 rigid transforms.

A pose is a 4x4 float64 matrix, camera-in-world (or base-in-world for the robot's planar pose).
World frame: z up. Camera frame: OpenCV (x right, y down, z forward).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


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
