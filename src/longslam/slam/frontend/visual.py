"""Frame-to-frame planar motion from image texture: tracked corners with depth on both ends.

In a straight corridor the depth band sees two parallel walls and nothing along the way, but
the floor, doors and posters carry texture. Corners are tracked with pyramidal Lucas-Kanade
(forward-backward checked), lifted to 3D with each frame's depth, and the planar rigid motion
of the robot base is fitted (2D Kabsch) to the pairs that agree with a predicted step. The
caller gates the result against the wheels: an RGB-D step is only trusted when it is near them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from longslam.core.frame import Intrinsics
from longslam.core.geometry.fit import rigid_transform_2d, weighted_planar_fit
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
    # Noisy depth (measured, depth_trust): a point's range is uncertain along its ray but its
    # bearing is not, so each pair is weighed by its own covariance and the step's heading holds
    # where its distance does not.
    noisy_max_sigma: float = param(0.3, "noisy depth: a corner with more range noise is left out", above=0, unit="m")
    noisy_patch: int = param(3, "noisy depth: a corner's depth, the median of (2n+1)^2 pixels", at_least=0, unit="px")
    noisy_gate: float = param(3.0, "noisy depth: a pair agrees with the step within this many of its stds", above=0)
    pixel_sigma: float = param(0.5, "noisy depth: std of a tracked corner's position", above=0, unit="px")
    # A corner's bearing is known to a tenth of a pixel, its depth to centimetres: fitted to the
    # bearings, with the robot's base moving along an arc (wheels do not slip sideways), the
    # heading no longer trades against a sideways shift the 3D fit cannot tell from it.
    arc_fit: bool = param(
        True, "with wheels: each step's heading refitted to where its corners are seen, the base on an arc"
    )
    arc_pixel_scale: float = param(
        1.0, "arc fit: reprojection error beyond which a corner counts less (Huber)", above=0, unit="px"
    )
    # On a tiled floor Lucas-Kanade can lock onto the next grout line, forward and back alike, so
    # the forward-backward check keeps the track; such tracks sit several pixels off the fit and
    # lean the same way, and Huber's weight still lets them pull the heading.
    arc_max_residual: float = param(
        1.5,
        "arc fit: corners further than this from the fitted step leave it and it is fitted again (0: kept)",
        at_least=0,
        unit="px",
    )

    def __post_init__(self) -> None:
        check_declared(self, "front end", "visual_tracking.")


@dataclass
class VisualStep:
    step: np.ndarray  # (3,) current base pose in the previous base frame
    inliers: int
    rms: float  # m
    covariance: np.ndarray | None = None  # (3, 3) of the step, fitted on noisy depth; None: exact depth


# A median of n Gaussian samples has about sqrt(pi / 2) times the std of their mean.
MEDIAN_EFFICIENCY = math.sqrt(math.pi / 2.0)
# The arc fit is made this many times at most, each after leaving out the corners far off the one
# before. On paper-300m (ideal seed 20 and Kinect seed 10, frames 0-600) 84 % of steps are done
# in two fits, 15 % in three and under 1 % reach the fourth.
MAX_ARC_ROUNDS = 4


class Tracks(NamedTuple):
    """Corners of one image and where Lucas-Kanade found them in the next."""

    previous: np.ndarray  # (N, 2) pixels in the earlier image
    current: np.ndarray  # (N, 2) pixels in the later image
    good: np.ndarray  # (N,) bool: tracked forward and back alike


@dataclass(frozen=True)
class TrackedAhead:
    """A frame's grey image and its corners tracked from the frame before it, worked out ahead
    of the front end's step (`FrontEnd.work_ahead`). `tracks` is None where too few corners were
    found; `tracked` False where they were not looked for (either frame's depth is tracked with
    its noise, which takes another mask), so the step tracks them itself."""

    gray: np.ndarray
    tracks: Tracks | None
    tracked: bool


def gray_image(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.asarray(rgb), cv2.COLOR_RGB2GRAY)


def near_mask(depth: np.ndarray, max_range: float) -> np.ndarray:
    """Where corners are looked for: returns within `max_range`."""
    return (depth > 0) & (depth <= max_range)


class CornerTracker:
    """Shi-Tomasi corners of one image tracked into the next by pyramidal Lucas-Kanade, forward
    and back. It keeps no state: the tracks are a function of the two images and the mask, so
    they may be worked out on another thread ahead of the step that uses them."""

    def __init__(self, intrinsics: Intrinsics, config: VisualConfig):
        self.config = config
        scale = intrinsics.width / 320.0
        self._min_distance = max(2, round(config.min_distance * scale))
        self.window = max(5, round(config.window * scale) | 1)  # odd

    def __call__(self, g0: np.ndarray, gray: np.ndarray, where: np.ndarray) -> Tracks | None:
        """Corners of the earlier image `g0` within the mask `where`, tracked into `gray`; None
        with fewer corners than `min_inliers`."""
        cfg = self.config
        p0 = cv2.goodFeaturesToTrack(g0, cfg.max_corners, cfg.quality, self._min_distance, mask=where.astype(np.uint8))
        if p0 is None or len(p0) < cfg.min_inliers:
            return None
        lk = dict(winSize=(self.window, self.window), maxLevel=cfg.levels)
        p1, st1, _ = cv2.calcOpticalFlowPyrLK(g0, gray, p0, None, **lk)
        back, st2, _ = cv2.calcOpticalFlowPyrLK(gray, g0, p1, None, **lk)
        fb = np.linalg.norm((back - p0).reshape(-1, 2), axis=1)
        good = (st1.ravel() == 1) & (st2.ravel() == 1) & (fb < cfg.max_fb_error)
        return Tracks(p0.reshape(-1, 2), p1.reshape(-1, 2), good)


def fit_arc_heading(
    project: Callable[[np.ndarray, float], np.ndarray],
    points: np.ndarray,
    seen: np.ndarray,
    yaw: float,
    config: VisualConfig,
) -> float | None:
    """The heading whose `project(points, heading)` (N, 2) puts the corners nearest where they
    are `seen` (N, 2), fitted from `yaw`; corners further than `config.arc_max_residual` pixels
    from the fitted step leave it and it is fitted again, while `config.min_inliers` remain.
    None where the fit has no curvature."""
    for _ in range(MAX_ARC_ROUNDS):
        fitted = _gauss_newton_heading(project, points, seen, yaw, config.arc_pixel_scale)
        if fitted is None:
            return None
        yaw = fitted
        if config.arc_max_residual <= 0:
            break
        near = np.linalg.norm(project(points, yaw) - seen, axis=1) < config.arc_max_residual
        if near.all() or near.sum() < config.min_inliers:
            break
        points, seen = points[near], seen[near]
    return yaw


def _gauss_newton_heading(
    project: Callable[[np.ndarray, float], np.ndarray],
    points: np.ndarray,
    seen: np.ndarray,
    yaw: float,
    pixel_scale: float,
) -> float | None:
    """Gauss-Newton in one unknown from `yaw`, Huber-weighted (scale `pixel_scale`) pixel residuals."""
    eps = 1e-6
    for _ in range(10):
        residual = (project(points, yaw) - seen).ravel()
        slope = ((project(points, yaw + eps) - seen).ravel() - residual) / eps
        weight = np.minimum(1.0, pixel_scale / np.maximum(np.abs(residual), 1e-12))
        curvature = float(slope @ (weight * slope))
        if not curvature > 0.0:
            return None
        update = float(slope @ (weight * residual)) / curvature
        yaw -= update
        if abs(update) < 1e-9:
            break
    return yaw


class VisualOdometry:
    def __init__(
        self,
        intrinsics: Intrinsics,
        camera_in_base: np.ndarray,
        config: VisualConfig | None = None,
        seed: int = 0,
        correlated: float = 1.0,
    ):
        self.config = config or VisualConfig()
        self.correlated = correlated  # pixels over which noisy depth's noise is correlated
        self.rng = np.random.default_rng(seed)
        self.corners = CornerTracker(intrinsics, self.config)
        self.k = intrinsics
        self.pose = np.asarray(camera_in_base, dtype=np.float64)
        self._prev: tuple[np.ndarray, np.ndarray, float | None] | None = None  # gray, depth, its noise sigma_w

    def _lift(self, pts: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel positions -> base-frame points (N, 3) and a validity mask."""
        h, w = depth.shape
        u = np.clip(np.rint(pts[:, 0]).astype(np.int64), 0, w - 1)
        v = np.clip(np.rint(pts[:, 1]).astype(np.int64), 0, h - 1)
        z = depth[v, u].astype(np.float64)
        ok = np.isfinite(z) & (z > 0) & (z <= self.config.max_range)
        cam = np.column_stack([(pts[:, 0] - self.k.cx) / self.k.fx * z, (pts[:, 1] - self.k.cy) / self.k.fy * z, z])
        return cam @ self.pose[:3, :3].T + self.pose[:3, 3], ok

    def _lift_noisy(
        self, pts: np.ndarray, depth: np.ndarray, sigma_w: float | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixel positions -> base-frame xy (N, 2), their (N, 2, 2) covariances and a validity
        mask, each corner's depth the median of its patch: the range noise sigma_w z^2 along the
        corner's ray, `pixel_sigma` across it."""
        cfg = self.config
        h, w = depth.shape
        r = cfg.noisy_patch
        offsets = np.arange(-r, r + 1)
        u = np.clip(np.rint(pts[:, 0]).astype(np.int64)[:, None, None] + offsets[None, None, :], 0, w - 1)
        v = np.clip(np.rint(pts[:, 1]).astype(np.int64)[:, None, None] + offsets[None, :, None], 0, h - 1)
        patch = depth[v, u].reshape(len(pts), -1).astype(np.float64)
        patch[~(np.isfinite(patch) & (patch > 0))] = np.nan
        count = np.sum(np.isfinite(patch), axis=1)
        z = np.full(len(pts), np.nan)
        some = count > 0
        z[some] = np.nanmedian(patch[some], axis=1)
        noise = sigma_w or 0.0
        sigma_z = noise * z * z * MEDIAN_EFFICIENCY / np.sqrt(np.maximum(count, 1) / self.correlated)
        ok = some & (sigma_z <= cfg.noisy_max_sigma)
        z = np.where(ok, z, 1.0)
        ray = np.column_stack(
            [(pts[:, 0] - self.k.cx) / self.k.fx, (pts[:, 1] - self.k.cy) / self.k.fy, np.ones(len(pts))]
        )
        rot = self.pose[:3, :3]
        base = (ray * z[:, None]) @ rot.T + self.pose[:3, 3]
        along = (ray @ rot.T)[:, :2] * sigma_z[:, None]
        across_x = rot[:2, 0][None, :] * (z * cfg.pixel_sigma / self.k.fx)[:, None]
        across_y = rot[:2, 1][None, :] * (z * cfg.pixel_sigma / self.k.fy)[:, None]
        cov = sum(np.einsum("ni,nj->nij", d, d) for d in (along, across_x, across_y)) + 1e-8 * np.eye(2)
        return base[:, :2], cov, ok

    def __call__(
        self,
        rgb: np.ndarray,
        depth: np.ndarray,
        predicted: np.ndarray | None,
        first_inlier: float | None = None,
        sigma_w: float | None = None,
        ahead: TrackedAhead | None = None,
    ) -> VisualStep | None:
        """The step from the previous frame to this one, fitted around `predicted` (x, y, yaw);
        pairs within `first_inlier` metres of the prediction start the fit. Without a
        prediction (no wheels), a two-point RANSAC finds the starting step. Depth of measured
        noise `sigma_w` (1/m, either frame's) is fitted point by point at its own noise, with
        the noise correlated over `self.correlated` pixels (`_noisy_step`). `ahead` holds this
        frame's grey image and tracks worked out ahead from these images (the same numbers)."""
        cfg = self.config
        gray = ahead.gray if ahead is not None else gray_image(rgb)
        depth = np.asarray(depth, dtype=np.float32)
        prev, self._prev = self._prev, (gray, depth, sigma_w)
        if prev is None:
            return None
        g0, d0, sigma_w0 = prev
        if (sigma_w is not None or sigma_w0 is not None) and predicted is not None:
            return self._noisy_step(g0, d0, sigma_w0, gray, depth, sigma_w, predicted, first_inlier)
        # Corners only where depth is near: in a hall most corners are on a ceiling or walls
        # beyond max_range, and they would crowd out the floor texture that fixes the step.
        if ahead is not None and ahead.tracked:
            tracked = ahead.tracks
        else:
            tracked = self.corners(g0, gray, near_mask(d0, cfg.max_range))
        if tracked is None:
            return None
        p0, p1, good = tracked
        lifted0, ok0 = self._lift(p0, d0)
        lifted1, ok1 = self._lift(p1, depth)
        good &= ok0 & ok1
        if good.sum() < cfg.min_inliers:
            return None
        # a = R b + t for the step (R, t) of the current base in the previous
        a, b = lifted0[good, :2], lifted1[good, :2]
        guessed = predicted is None  # no wheels: nothing says the base moves along an arc
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
        rms = float(np.sqrt(np.mean(res**2)))
        if cfg.arc_fit and not guessed:
            arc = self._arc_step(g0, gray, p0[ok0], lifted0[ok0], step)
            if arc is not None:
                return VisualStep(arc, int(inl.sum()), rms)
        return VisualStep(step, int(inl.sum()), rms)

    def _arc_step(
        self, g0: np.ndarray, gray: np.ndarray, p0: np.ndarray, lifted: np.ndarray, start: np.ndarray
    ) -> np.ndarray | None:
        """The step `start` (x, y, yaw) refitted along an arc, (d cos(yaw / 2), d sin(yaw / 2),
        yaw), its distance d kept from `start` and its heading the one that best reprojects the
        corners `p0` of the earlier image, `lifted` (N, 3) into its base frame, onto where Lucas-Kanade
        finds them in this one. They are tracked again from where `start` puts them: from no
        motion, a turn's shift of ten pixels is found a little short (about 1 % of the turn). The
        distance is not refitted: from the bearings alone it comes out short by about 2 %, as a
        corner's patch grows between the images. None with too few corners tracked."""
        cfg = self.config
        k = self.k
        in_base = np.column_stack([lifted, np.ones(len(lifted))])  # homogeneous
        to_camera = np.linalg.inv(self.pose)
        distance = start[0] / math.cos(start[2] / 2)

        def project(points: np.ndarray, yaw: float) -> np.ndarray:
            c, s = math.cos(yaw), math.sin(yaw)
            x, y = distance * math.cos(yaw / 2), distance * math.sin(yaw / 2)
            base_inverse = np.array([[c, s, 0, -c * x - s * y], [-s, c, 0, s * x - c * y], [0, 0, 1, 0], [0, 0, 0, 1]])
            q = points @ (to_camera @ base_inverse).T
            depth = np.maximum(q[:, 2], 1e-6)
            return np.column_stack([k.fx * q[:, 0] / depth + k.cx, k.fy * q[:, 1] / depth + k.cy])

        first = p0.astype(np.float32).reshape(-1, 1, 2)
        guess = project(in_base, float(start[2])).astype(np.float32).reshape(-1, 1, 2)
        lk = dict(
            winSize=(self.corners.window, self.corners.window),
            maxLevel=cfg.levels,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.001),
        )
        p1, st1, _ = cv2.calcOpticalFlowPyrLK(g0, gray, first, guess, **lk)
        back, st2, _ = cv2.calcOpticalFlowPyrLK(gray, g0, p1, first.copy(), **lk)
        fb = np.linalg.norm((back - first).reshape(-1, 2), axis=1)
        good = (st1.ravel() == 1) & (st2.ravel() == 1) & (fb < cfg.max_fb_error)
        if good.sum() < cfg.min_inliers:
            return None
        yaw = fit_arc_heading(project, in_base[good], p1.reshape(-1, 2)[good], float(start[2]), cfg)
        if yaw is None:
            return None
        return np.array([distance * math.cos(yaw / 2), distance * math.sin(yaw / 2), yaw])

    def _noisy_step(
        self,
        g0: np.ndarray,
        d0: np.ndarray,
        sigma_w0: float | None,
        gray: np.ndarray,
        depth: np.ndarray,
        sigma_w: float | None,
        predicted: np.ndarray,
        first_inlier: float | None,
    ) -> VisualStep | None:
        """The step on noisy depth: corners wherever the patch median's noise is within
        `noisy_max_sigma`, the step fitted by each pair's own covariance (first widened by
        `first_inlier` around the prediction), with the fit's covariance."""
        cfg = self.config
        noise = max(sigma_w0 or 0.0, sigma_w or 0.0)
        reach = math.sqrt(cfg.noisy_max_sigma * math.sqrt((2 * cfg.noisy_patch + 1) ** 2 / self.correlated) / noise)
        tracked = self.corners(g0, gray, near_mask(d0, reach))
        if tracked is None:
            return None
        p0, p1, good = tracked
        a, cov_a, ok0 = self._lift_noisy(p0, d0, sigma_w0)
        b, cov_b, ok1 = self._lift_noisy(p1, depth, sigma_w)
        good &= ok0 & ok1
        if good.sum() < cfg.min_inliers:
            return None
        a, b, cov_a, cov_b = a[good], b[good], cov_a[good], cov_b[good]
        c, s = np.cos(predicted[2]), np.sin(predicted[2])
        rot = np.array([[c, -s], [s, c]])
        cov = cov_a + rot @ cov_b @ rot.T
        widen = (cfg.first_inlier if first_inlier is None else first_inlier) / cfg.noisy_gate
        start, _, _ = weighted_planar_fit(b, a, cov + widen**2 * np.eye(2), predicted, cfg.noisy_gate, 2)
        step, step_cov, inl = weighted_planar_fit(b, a, cov, start, cfg.noisy_gate, 4)
        if inl.sum() < cfg.min_inliers or not np.all(np.isfinite(step_cov)):
            return None
        c, s = np.cos(step[2]), np.sin(step[2])
        res = np.linalg.norm(b[inl] @ np.array([[c, -s], [s, c]]).T + step[:2] - a[inl], axis=1)
        return VisualStep(step, int(inl.sum()), float(np.sqrt(np.mean(res**2))), step_cov)

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
