"""Aligning an estimated trajectory to the reference: Umeyama's least-squares SE(3) / Sim(3) fit.

Same definition as evo's `geometry.umeyama_alignment` and `PosePath3D.align` (positions only; the
fitted transform is then applied to whole poses), so aligned APE agrees with `evo_ape -a / -as`.
"""

from __future__ import annotations

import numpy as np

from longslam.errors import TrajectoryError, UnknownNameError
from longslam.eval.sync import require_same_length
from longslam.trajectory import Trajectory

ALIGN_MODES = ("none", "se3", "sim3")

# Second singular value of the cross-covariance below this fraction of the first: the points lie
# on a line (or a point) and the rotation about that line is not determined by the data.
DEGENERATE_RATIO = 1e-10


def umeyama(
    source: np.ndarray, target: np.ndarray, with_scale: bool
) -> tuple[np.ndarray, np.ndarray, float]:
    """R (3, 3), t (3,), s minimising sum ||target_i - (s R source_i + t)||^2 (s = 1 unless with_scale).

    Umeyama, "Least-squares estimation of transformation parameters between two point patterns",
    IEEE PAMI 1991, eqs. 34-43. Raises TrajectoryError for fewer than 3 points or collinear points.
    """
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3:
        raise TrajectoryError(
            f"alignment needs two (N, 3) point arrays of the same shape, "
            f"got {source.shape} and {target.shape}"
        )
    n = len(source)
    if n < 3:
        raise TrajectoryError(f"alignment needs at least 3 matched positions, got {n}")

    mean_source, mean_target = source.mean(axis=0), target.mean(axis=0)
    centred_source, centred_target = source - mean_source, target - mean_target
    variance_source = np.sum(centred_source**2) / n
    covariance = centred_target.T @ centred_source / n
    u, d, vt = np.linalg.svd(covariance)
    if d[1] <= DEGENERATE_RATIO * d[0]:
        raise TrajectoryError(
            f"cannot align: the {n} positions lie on a straight line (or a single point), so the "
            f"rotation about that line is undetermined; use align='none'"
        )
    # Flip the weakest axis if needed so that R is a rotation, not a reflection.
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        sign[2, 2] = -1.0
    rotation = u @ sign @ vt
    scale = float(np.trace(np.diag(d) @ sign) / variance_source) if with_scale else 1.0
    translation = mean_target - scale * rotation @ mean_source
    return rotation, translation, scale


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
