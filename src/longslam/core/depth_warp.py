"""A depth image seen again from a camera moved a little: the warp a depth stream out of step
with its colour stream needs, whichever side (the simulator's perturbation, a run's compensation)."""

from __future__ import annotations

import cv2
import numpy as np

from longslam.core.frame import Intrinsics


def move_at_velocity(
    angular_velocity: np.ndarray, linear_velocity: np.ndarray, seconds: float
) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, position) of a camera `seconds` on (before, for negative seconds) in the frame of
    the camera now, moving at `angular_velocity` (rad/s) and `linear_velocity` (m/s) in its own
    axes, held constant: first order in the move, as over a step or two it is small."""
    rotation = cv2.Rodrigues(np.asarray(angular_velocity, dtype=np.float64) * seconds)[0]
    return rotation, np.asarray(linear_velocity, dtype=np.float64) * seconds


def reproject_depth(
    depth: np.ndarray, intrinsics: Intrinsics, rotation: np.ndarray, position: np.ndarray
) -> np.ndarray:
    """`depth` as seen by a camera at `position` with `rotation` in this camera's frame: each
    return moved and projected, the nearest kept where several land on one pixel; one-pixel cracks
    of that forward warp filled from the nearer of their two neighbours, uncovered areas left at 0."""
    h, w = depth.shape
    v, u = np.nonzero(depth > 0)
    z = depth[v, u].astype(np.float64)
    k = intrinsics
    points = np.stack([(u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z], axis=1)
    seen = (points - position) @ rotation  # R^T (X - p), row by row
    ahead = seen[:, 2] > 1e-6
    seen = seen[ahead]
    pu = np.rint(k.fx * seen[:, 0] / seen[:, 2] + k.cx).astype(np.int64)
    pv = np.rint(k.fy * seen[:, 1] / seen[:, 2] + k.cy).astype(np.int64)
    inside = (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h)
    flat = np.full(h * w, np.inf)
    np.minimum.at(flat, pv[inside] * w + pu[inside], seen[inside, 2])
    out = flat.reshape(h, w)
    # A crack is a hole with returns on both sides, across or along: a surface stretched by the
    # move, not one uncovered.
    padded = np.pad(out, 1, constant_values=np.inf)
    left, right, up, down = padded[1:-1, :-2], padded[1:-1, 2:], padded[:-2, 1:-1], padded[2:, 1:-1]
    across = np.where(np.isfinite(left) & np.isfinite(right), np.minimum(left, right), np.inf)
    along = np.where(np.isfinite(up) & np.isfinite(down), np.minimum(up, down), np.inf)
    out = np.where(np.isfinite(out), out, np.minimum(across, along))
    return np.where(np.isfinite(out), out, 0.0).astype(np.float32)
