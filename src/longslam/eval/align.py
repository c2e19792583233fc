"""Aligning an estimated trajectory to the reference: Umeyama's least-squares SE(3) / Sim(3) fit.

Same definition as evo's `geometry.umeyama_alignment` and `PosePath3D.align` (positions only; the
fitted transform is then applied to whole poses), so aligned APE agrees with `evo_ape -a / -as`.
"""

from __future__ import annotations

import numpy as np

from longslam.errors import UnknownNameError
from longslam.eval.sync import require_same_length
from longslam.geometry.fit import umeyama  # noqa: F401  (re-exported: evaluation's alignment)
from longslam.trajectory import Trajectory

ALIGN_MODES = ("none", "se3", "sim3")

def transform_trajectory(
    trajectory: Trajectory, rotation: np.ndarray, translation: np.ndarray, scale: float = 1.0
) -> Trajectory:
    """Apply x -> s R x + t to every position and R to every orientation (evo: scale, then transform)."""
    poses = trajectory.poses.copy()
    poses[:, :3, :3] = rotation @ trajectory.poses[:, :3, :3]
    poses[:, :3, 3] = scale * trajectory.positions @ rotation.T + translation
    return Trajectory(trajectory.timestamps, poses, trajectory.source)


def alignment(estimate: Trajectory, reference: Trajectory, mode: str) -> tuple[np.ndarray, np.ndarray, float]:
    """The (R, t, s) that `align_trajectory` applies for `mode` (identity for 'none')."""
    if mode not in ALIGN_MODES:
        raise UnknownNameError("alignment mode", mode, ALIGN_MODES)
    require_same_length(reference, estimate)
    if mode == "none":
        return np.eye(3), np.zeros(3), 1.0
    return umeyama(estimate.positions, reference.positions, with_scale=mode == "sim3")


def align_trajectory(estimate: Trajectory, reference: Trajectory, mode: str) -> Trajectory:
    """The estimate moved (and for 'sim3' scaled) onto the associated reference.

    mode: 'none' (returned unchanged), 'se3' (rotation and translation) or 'sim3' (plus scale).
    """
    rotation, translation, scale = alignment(estimate, reference, mode)
    if mode == "none":
        return estimate
    return transform_trajectory(estimate, rotation, translation, scale)
