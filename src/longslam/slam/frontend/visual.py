"""Frame-to-frame planar motion from image texture: tracked corners with depth on both ends.

In a straight corridor the depth band sees two parallel walls and nothing along the way, but
the floor, doors and posters carry texture. Corners are tracked with pyramidal Lucas-Kanade
(forward-backward checked), lifted to 3D with each frame's depth, and the planar rigid motion
of the robot base is fitted (2D Kabsch) to the pairs that agree with a predicted step. The
caller gates the result against the wheels: an RGB-D step is only trusted when it is near them.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from longslam.core.frame import Intrinsics
from longslam.core.geometry.fit import rigid_transform_2d
from longslam.core.parameter import check_declared, param


@dataclass(frozen=True)
class VisualConfig:
    max_corners: int = param(150, "corners tracked per frame (Shi-Tomasi)", at_least=1)
    quality: float = param(
        0.01, "corner quality level, a fraction of the best corner's (OpenCV goodFeaturesToTrack)", above=0, at_most=1
    )
    min_distance: int = param(7, "corner spacing at 320 px wide, scaled with the image width", at_least=0, unit="px")
    window: int = param(11, "Lucas-Kanade window at 320 px wide, scaled with the image width", at_least=1, unit="px")
    levels: int = param(2, "Lucas-Kanade pyramid levels above the image itself", at_least=0)
    max_range: float = param(4.0, "farther points move by under a pixel per step, left out", above=0, unit="m")
    max_fb_error: float = param(0.5, "forward-backward tracking disagreement a corner may have", above=0, unit="px")
    inlier: float = param(0.03, "distance within which a pair agrees with the fitted step", above=0, unit="m")
    first_inlier: float = param(0.08, "distance within which a pair agrees with the predicted step", above=0, unit="m")
    min_inliers: int = param(
        20, "tracked pairs that must agree for an RGB-D step", at_least=2, why="a planar step needs two points"
    )

    def __post_init__(self) -> None:
        check_declared(self, "front end", "visual_tracking.")


@dataclass
class VisualStep:
    step: np.ndarray  # (3,) current base pose in the previous base frame
    inliers: int
    rms: float  # m


class VisualOdometry:
    def __init__(
        self, intrinsics: Intrinsics, camera_in_base: np.ndarray, config: VisualConfig | None = None, seed: int = 0
    ):
        self.config = config or VisualConfig()
        self.rng = np.random.default_rng(seed)
        scale = intrinsics.width / 320.0
        self._min_distance = max(2, round(self.config.min_distance * scale))
        self._window = max(5, round(self.config.window * scale) | 1)  # odd
        self.k = intrinsics
        self.pose = np.asarray(camera_in_base, dtype=np.float64)
        self._prev: tuple[np.ndarray, np.ndarray] | None = None  # gray, depth

    def _lift(self, pts: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel positions -> base-frame xy (N, 2) and a validity mask."""
        h, w = depth.shape
        u = np.clip(np.rint(pts[:, 0]).astype(np.int64), 0, w - 1)
        v = np.clip(np.rint(pts[:, 1]).astype(np.int64), 0, h - 1)
        z = depth[v, u].astype(np.float64)
        ok = np.isfinite(z) & (z > 0) & (z <= self.config.max_range)
        cam = np.column_stack([(pts[:, 0] - self.k.cx) / self.k.fx * z, (pts[:, 1] - self.k.cy) / self.k.fy * z, z])
        base = cam @ self.pose[:3, :3].T + self.pose[:3, 3]
        return base[:, :2], ok

    def __call__(
        self, rgb: np.ndarray, depth: np.ndarray, predicted: np.ndarray | None, first_inlier: float | None = None
    ) -> VisualStep | None:
        """The step from the previous frame to this one, fitted around `predicted` (x, y, yaw);
        pairs within `first_inlier` metres of the prediction start the fit. Without a
        prediction (no wheels), a two-point RANSAC finds the starting step."""
        cfg = self.config
        gray = cv2.cvtColor(np.asarray(rgb), cv2.COLOR_RGB2GRAY)
        depth = np.asarray(depth, dtype=np.float32)
        prev, self._prev = self._prev, (gray, depth)
        if prev is None:
            return None
        g0, d0 = prev
        # Corners only where depth is near: in a hall most corners are on a ceiling or walls
        # beyond max_range, and they would crowd out the floor texture that fixes the step.
        mask = ((d0 > 0) & (d0 <= cfg.max_range)).astype(np.uint8)
        p0 = cv2.goodFeaturesToTrack(g0, cfg.max_corners, cfg.quality, self._min_distance, mask=mask)
        if p0 is None or len(p0) < cfg.min_inliers:
            return None
        lk = dict(winSize=(self._window, self._window), maxLevel=cfg.levels)
        p1, st1, _ = cv2.calcOpticalFlowPyrLK(g0, gray, p0, None, **lk)
        back, st2, _ = cv2.calcOpticalFlowPyrLK(gray, g0, p1, None, **lk)
        fb = np.linalg.norm((back - p0).reshape(-1, 2), axis=1)
        good = (st1.ravel() == 1) & (st2.ravel() == 1) & (fb < cfg.max_fb_error)
        a, ok0 = self._lift(p0.reshape(-1, 2), d0)
        b, ok1 = self._lift(p1.reshape(-1, 2), depth)
        good &= ok0 & ok1
        if good.sum() < cfg.min_inliers:
            return None
        a, b = a[good], b[good]  # a = R b + t for the step (R, t) of the current base in the previous
        if predicted is None:
            predicted = self._ransac(a, b)
            first_inlier = cfg.inlier
        c, s = np.cos(predicted[2]), np.sin(predicted[2])
        rot, t = np.array([[c, -s], [s, c]]), np.asarray(predicted[:2], dtype=np.float64)
        threshold = cfg.first_inlier if first_inlier is None else first_inlier
        inl = np.zeros(len(a), dtype=bool)
        for _ in range(3):
            res = np.linalg.norm(b @ rot.T + t - a, axis=1)
            inl = res < threshold
            if inl.sum() < cfg.min_inliers:
                return None
            rot, t = rigid_transform_2d(b[inl], a[inl])
            threshold = cfg.inlier
        res = np.linalg.norm(b[inl] @ rot.T + t - a[inl], axis=1)
        step = np.array([t[0], t[1], np.arctan2(rot[1, 0], rot[0, 0])])
        return VisualStep(step, int(inl.sum()), float(np.sqrt(np.mean(res**2))))

    def _ransac(self, a: np.ndarray, b: np.ndarray, hypotheses: int = 64) -> np.ndarray:
        """Best planar step (x, y, yaw) with a = R b + t over random pairs of pairs, all at once."""
        i = self.rng.integers(0, len(a), size=(hypotheses, 2))
        da, db = a[i[:, 1]] - a[i[:, 0]], b[i[:, 1]] - b[i[:, 0]]
        angle = np.arctan2(da[:, 1], da[:, 0]) - np.arctan2(db[:, 1], db[:, 0])
        c, s = np.cos(angle), np.sin(angle)
        b0 = b[i[:, 0]]
        t = a[i[:, 0]] - np.column_stack([c * b0[:, 0] - s * b0[:, 1], s * b0[:, 0] + c * b0[:, 1]])
        px = c[:, None] * b[None, :, 0] - s[:, None] * b[None, :, 1] + t[:, :1]
        py = s[:, None] * b[None, :, 0] + c[:, None] * b[None, :, 1] + t[:, 1:]
        inliers = ((px - a[None, :, 0]) ** 2 + (py - a[None, :, 1]) ** 2 < self.config.inlier**2).sum(axis=1)
        best = int(np.argmax(inliers))
        return np.array([t[best, 0], t[best, 1], angle[best]])
