"""Rigid (or similarity) fits between matched point sets: Umeyama's least squares in 3D, and its
closed form in the plane.

Used to align a trajectory to its reference (evaluation), to polish a loop transform on matched
3D points (place recognition) and to fit the robot's step to tracked corners (the front end). Same definition as
evo's `geometry.umeyama_alignment`.
"""

from __future__ import annotations

import numpy as np

from longslam.core.errors import TrajectoryError

# Second singular value of the cross-covariance below this fraction of the first: the points lie
# on a line (or a point) and the rotation about that line is not determined by the data.
DEGENERATE_RATIO = 1e-10


def umeyama(
    source: np.ndarray, target: np.ndarray, with_scale: bool, allow_degenerate: bool = False
) -> tuple[np.ndarray, np.ndarray, float]:
    """R (3, 3), t (3,), s minimising sum ||target_i - (s R source_i + t)||^2 (s = 1 unless with_scale).

    Umeyama, "Least-squares estimation of transformation parameters between two point patterns",
    IEEE PAMI 1991, eqs. 34-43. Raises TrajectoryError for fewer than 3 points, or for collinear
    points unless `allow_degenerate` (then one of the equally good rotations is returned).
    """
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3:
        raise TrajectoryError(
            f"alignment needs two (N, 3) point arrays of the same shape, " f"got {source.shape} and {target.shape}"
        )
    n = len(source)
    if n < 3:
        raise TrajectoryError(f"alignment needs at least 3 matched positions, got {n}")

    mean_source, mean_target = source.mean(axis=0), target.mean(axis=0)
    centred_source, centred_target = source - mean_source, target - mean_target
    variance_source = np.sum(centred_source**2) / n
    covariance = centred_target.T @ centred_source / n
    u, d, vt = np.linalg.svd(covariance)
    if d[1] <= DEGENERATE_RATIO * d[0] and not allow_degenerate:
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


def rigid_transform(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The 4x4 rigid transform T minimising sum ||target_i - T(source_i)||^2."""
    rotation, translation, _ = umeyama(source, target, with_scale=False, allow_degenerate=True)
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


def rigid_transform_2d(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R (2, 2), t (2,) minimising sum ||R source_i + t - target_i||^2 for (N, 2) points: the
    planar case in closed form (one atan2, no SVD), cheap enough for a RANSAC loop."""
    mean_source, mean_target = source.mean(axis=0), target.mean(axis=0)
    h = (source - mean_source).T @ (target - mean_target)
    angle = np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.array([[c, -s], [s, c]])
    return rotation, mean_target - rotation @ mean_source


def weighted_planar_fit(
    source: np.ndarray,
    target: np.ndarray,
    covariances: np.ndarray,
    start: np.ndarray,
    gate: float,
    iterations: int = 5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The planar step (x, y, yaw) with target = R source + t, fitted by Gauss-Newton from `start`
    where each pair's residual has its own (N, 2, 2) covariance (given in the target's frame):
    (the step, its 3 x 3 covariance, the inlier mask). Pairs beyond `gate` Mahalanobis stds are
    left out at each iteration; with fewer than two inliers the covariance is infinite."""
    step = np.asarray(start, dtype=np.float64).copy()
    information = np.linalg.inv(covariances)
    inliers = np.zeros(len(source), dtype=bool)
    hessian = np.zeros((3, 3))
    for _ in range(iterations):
        c, s = np.cos(step[2]), np.sin(step[2])
        rotated = np.column_stack([c * source[:, 0] - s * source[:, 1], s * source[:, 0] + c * source[:, 1]])
        residual = rotated + step[:2] - target
        mahalanobis = np.einsum("ni,nij,nj->n", residual, information, residual)
        inliers = mahalanobis < gate * gate
        if inliers.sum() < 2:
            return step, np.full((3, 3), np.inf), inliers
        jacobian = np.zeros((len(source), 2, 3))
        jacobian[:, 0, 0] = jacobian[:, 1, 1] = 1.0
        jacobian[:, :, 2] = np.column_stack([-rotated[:, 1], rotated[:, 0]])
        j, w, r = jacobian[inliers], information[inliers], residual[inliers]
        hessian = np.einsum("nki,nkl,nlj->ij", j, w, j)
        gradient = np.einsum("nki,nkl,nl->i", j, w, r)
        step -= np.linalg.solve(hessian, gradient)
    return step, np.linalg.inv(hessian), inliers
