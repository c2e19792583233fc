"""Submap-to-submap registration, Voxgraph's "explicit to implicit" way, over (x, y, yaw).

Iso-surface points of the reading submap B (explicit) are moved into the reference submap A by
the relative pose T_AB and looked up in A's signed distance field (implicit); the cost is the sum
of the squared distances, which is zero when B's surface lies on A's. It is minimised with
Gauss-Newton on analytic Jacobians (the trilinear gradient of A's field), with Huber weights
against points that land on structure only one submap saw.

The pose is perturbed on the right, T_AB <- T_AB * Exp(dx, dy, dyaw), which is the tangent space
of GTSAM's BetweenFactor<Pose2>: the Gauss-Newton Hessian at the optimum is then directly the
information of the constraint, with the degenerate direction of a straight corridor left (almost)
unconstrained instead of being pinned by a made-up diagonal.

A result is accepted only if it converged, enough points overlapped the reference's observed
volume, their RMS distance is small, and the correction to the initial guess is within bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.geometry import compose_xyyaw
from longslam.slam.submap.tsdf import TSDF


@dataclass(frozen=True)
class RegistrationSettings:
    max_iterations: int = 30
    min_points: int = 100  # overlapping points needed to accept
    min_overlap_fraction: float = 0.05  # of the reading points
    max_rms: float = 0.08  # metres, RMS distance of the overlapping points at the optimum
    max_translation: float = 2.0  # metres of correction to the initial guess
    max_rotation: float = 0.26  # radians (15 degrees)
    huber: float = 0.1  # metres
    residual_sigma: float = 0.05  # metres: per-point noise of the distance lookups
    effective_points: float = 20.0  # independent measurements the point set is worth
    max_step: float = 0.3  # metres per iteration (radians / 3 for yaw)


@dataclass
class RegistrationResult:
    accepted: bool
    reason: str
    relative: np.ndarray  # (3,) x, y, yaw of B's origin in A's frame (the estimate, accepted or not)
    information: np.ndarray  # (3, 3) in the right-perturbation tangent space
    rms: float
    overlap: int
    iterations: int
    converged: bool


def _transform(points: np.ndarray, xyyaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(xyyaw[2]), np.sin(xyyaw[2])
    out = points.copy()
    out[:, 0] = c * points[:, 0] - s * points[:, 1] + xyyaw[0]
    out[:, 1] = s * points[:, 0] + c * points[:, 1] + xyyaw[1]
    return out


def _linearise(reference: TSDF, points: np.ndarray, xyyaw: np.ndarray, huber: float):
    """Residuals, Jacobians (right perturbation) and Huber weights of the overlapping points."""
    moved = _transform(points, xyyaw)
    value, grad, valid = reference.interpolate(moved, min_weight=0.0)
    r = value[valid]
    g = grad[valid]
    p = points[valid]
    c, s = np.cos(xyyaw[2]), np.sin(xyyaw[2])
    # Gradient in B's frame (2D part): R^T g.
    gx = c * g[:, 0] + s * g[:, 1]
    gy = -s * g[:, 0] + c * g[:, 1]
    jac = np.column_stack([gx, gy, -gx * p[:, 1] + gy * p[:, 0]])
    a = np.abs(r)
    w = np.where(a <= huber, 1.0, huber / np.maximum(a, 1e-12))
    return r, jac, w, int(valid.sum())


def register(
    reference: TSDF,
    points: np.ndarray,
    initial: np.ndarray,
    settings: RegistrationSettings = RegistrationSettings(),
) -> RegistrationResult:
    """Align `points` (N, 3, in B's frame) to `reference` (A) starting from `initial` = (x, y, yaw)
    of B in A. Never raises on bad data: a failure is a rejected result with its reason."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    initial = np.asarray(initial, dtype=np.float64).reshape(3)
    x = initial.copy()
    zero = np.zeros((3, 3))
    if len(points) < settings.min_points:
        return RegistrationResult(
            False, f"{len(points)} surface points, need {settings.min_points}", x, zero, np.nan, 0, 0, False
        )
    converged = False
    iterations = 0
    for iterations in range(1, settings.max_iterations + 1):
        r, jac, w, n = _linearise(reference, points, x, settings.huber)
        if n < settings.min_points:
            return RegistrationResult(
                False, f"{n} points overlap, need {settings.min_points}", x, zero, np.nan, n, iterations, False
            )
        jw = jac * w[:, None] / settings.residual_sigma**2
        h = jac.T @ jw
        b = jw.T @ r
        h_damped = h + np.diag(np.maximum(np.diag(h), 1e-9)) * 1e-3 + np.eye(3) * 1e-9
        try:
            step = -np.linalg.solve(h_damped, b)
        except np.linalg.LinAlgError:
            return RegistrationResult(False, "singular normal equations", x, zero, np.nan, n, iterations, False)
        if not np.all(np.isfinite(step)):
            return RegistrationResult(False, "non-finite step", x, zero, np.nan, n, iterations, False)
        scale = max(np.linalg.norm(step[:2]) / settings.max_step, abs(step[2]) / (settings.max_step / 3.0), 1.0)
        step = step / scale
        x = compose_xyyaw(x, step)
        if np.linalg.norm(step[:2]) < 1e-3 and abs(step[2]) < 1e-4:
            converged = True
            break
    r, jac, w, n = _linearise(reference, points, x, settings.huber)
    rms = float(np.sqrt(np.mean(r**2))) if n else float("nan")
    information = np.zeros((3, 3))
    if n:
        h = (jac * w[:, None]).T @ jac
        information = h / max(n, 1) * settings.effective_points / settings.residual_sigma**2
        information = 0.5 * (information + information.T) + np.eye(3) * 1e-6
    dyaw = (x[2] - initial[2] + np.pi) % (2 * np.pi) - np.pi
    moved = float(np.linalg.norm(x[:2] - initial[:2]))
    result = RegistrationResult(False, "", x, information, rms, n, iterations, converged)
    if not converged:
        result.reason = f"did not converge in {settings.max_iterations} iterations"
    elif n < settings.min_points or n < settings.min_overlap_fraction * len(points):
        result.reason = f"{n} of {len(points)} points overlap"
    elif not rms <= settings.max_rms:
        result.reason = f"RMS distance {rms:.3f} m > {settings.max_rms} m"
    elif moved > settings.max_translation or abs(dyaw) > settings.max_rotation:
        result.reason = f"correction {moved:.2f} m / {np.degrees(dyaw):.1f} deg out of bounds"
    else:
        result.accepted = True
        result.reason = f"{n} points, RMS {rms:.3f} m, {iterations} iterations"
    return result
