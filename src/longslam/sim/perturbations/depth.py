"""The depth image perturbed: out of step with the colour, and lost in bursts."""

from __future__ import annotations

import cv2
import numpy as np

from longslam.core.frame import Intrinsics
from longslam.sim.perturbations.base import FrameContext, Perturbation
from longslam.sim.perturbations.stretches import PERIOD_S, in_stretch


class DepthOffset(Perturbation):
    """Colour and depth out of step: the depth delivered with a colour image stamped t is the
    scene as seen from where the camera was at t - level (a positive level: depth lags colour; a
    negative one: it leads), both still stamped t, as with a camera whose two streams are not
    synchronised. The depth is the frame's own, reprojected into that pose (the camera's true
    velocity during the frame, held constant over the offset), so any offset works, not only whole
    frames of the render; pixels the move uncovers have no return (0)."""

    name = "depth-offset"
    default_level = 0.05
    low = -0.5
    high = 0.5
    meaning = "seconds the depth lags the colour (negative: leads), not 0, between -0.5 and 0.5"

    @classmethod
    def level_problem(cls, level: float) -> str | None:
        if level == 0:
            return f"level 0 changes nothing; expected {cls.meaning}"
        return super().level_problem(level)

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        motion = frame.motion
        seconds = -self.level  # the depth's moment, relative to the colour's
        rotation = cv2.Rodrigues(np.asarray(motion.angular_velocity, dtype=np.float64) * seconds)[0]
        moved = np.asarray(motion.linear_velocity, dtype=np.float64) * seconds
        return rgb, reproject_depth(depth, frame.intrinsics, rotation, moved)


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


class DepthDropout(Perturbation):
    """Depth lost in bursts: every pixel without a return for `level` seconds, once in each minute
    of the route (a USB stream stalling, another camera's projector, sunlight), colour unaffected."""

    name = "depth-dropout"
    default_level = 1.0
    high = PERIOD_S / 2
    meaning = f"seconds without depth, one burst a minute, > 0 and <= {PERIOD_S / 2:g}"

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        if in_stretch(self.name, frame.seed, frame.timestamp, frame.start, frame.end, self.level):
            return rgb, np.zeros_like(depth)
        return rgb, depth
