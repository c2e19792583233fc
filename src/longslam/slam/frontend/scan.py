"""Depth image -> 2D scan in the robot's floor frame (x forward, y left).

Only the band of heights where walls, doors and furniture stand (0.2-1.5 m above the floor by
default, the same band as the occupancy grid) is kept: floor and ceiling carry no planar
geometry and would dominate a 3D cloud. The points are averaged per 5 cm cell so that near
walls (many pixels per cell) do not outweigh far ones, and the scan stays ~100-300 points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.geometry.cells import average_2d
from longslam.core.parameter import check_declared, param


@dataclass(frozen=True)
class ScanConfig:
    min_height: float = param(0.2, "depth points lower above the floor are not part of the scan", at_least=0, unit="m")
    max_height: float = param(1.5, "depth points higher above the floor are not part of the scan", above=0, unit="m")
    min_range: float = param(
        0.3, "closer returns (horizontal) are the robot's own blind zone, left out", at_least=0, unit="m"
    )
    max_range: float = param(8.0, "farther returns (horizontal) are left out of the scan", above=0, unit="m")
    cell: float = param(0.05, "size of the cells the scan's points are averaged in", above=0, unit="m")
    # 0 gives 2 at 320 x 240: plenty for 5 cm cells, and a small image keeps every pixel.
    stride: int = param(0, "pixel stride of the scan; 0: about 160 columns whatever the image width", at_least=0)

    def __post_init__(self) -> None:
        check_declared(self, "front end", "scan.")
        if self.max_height <= self.min_height or self.max_range <= self.min_range:
            raise InputError("front end: scan.max_height and scan.max_range must exceed their min_height and min_range")


class ScanExtractor:
    """Vectorised depth -> scan. The per-pixel ray directions are computed once per camera."""

    def __init__(self, intrinsics: Intrinsics, camera_in_base: np.ndarray, config: ScanConfig | None = None):
        self.config = config or ScanConfig()
        self.intrinsics = intrinsics
        s = int(self.config.stride) or max(1, round(intrinsics.width / 160))
        v, u = np.mgrid[0 : intrinsics.height : s, 0 : intrinsics.width : s]
        rays = np.stack(
            [(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones(u.shape)], axis=-1
        ).reshape(-1, 3)
        pose = np.asarray(camera_in_base, dtype=np.float64)
        # A base-frame point is depth * (R @ ray) + t: precompute R @ ray for every pixel, one
        # contiguous array per axis (picking pixels out of an (N, 3) array costs several times more).
        dirs = (rays @ pose[:3, :3].T).astype(np.float32)
        self._dir_x, self._dir_y, self._dir_z = (np.ascontiguousarray(dirs[:, axis]) for axis in range(3))
        self._origin = pose[:3, 3].astype(np.float32)
        self._stride = s

    def __call__(self, depth: np.ndarray) -> np.ndarray:
        """(N, 2) float64 cell-averaged scan points in the base frame."""
        cfg = self.config
        z = np.asarray(depth, dtype=np.float32)[:: self._stride, :: self._stride].reshape(-1)
        pixels = np.flatnonzero(np.isfinite(z) & (z > 0))
        # Height first, then only the band's points get their x, y.
        z = z[pixels]
        h = z * self._dir_z[pixels] + self._origin[2]
        band = (h >= cfg.min_height) & (h <= cfg.max_height)
        z, pixels = z[band], pixels[band]
        xy = np.empty((len(z), 2), np.float32)
        xy[:, 0] = z * self._dir_x[pixels] + self._origin[0]
        xy[:, 1] = z * self._dir_y[pixels] + self._origin[1]
        r2 = np.einsum("ij,ij->i", xy, xy)
        keep = (r2 >= cfg.min_range**2) & (r2 <= cfg.max_range**2)
        return average_2d(xy[keep].astype(np.float64), cfg.cell)

    def columns(
        self, depth: np.ndarray, sigma_w: float, min_returns: int, max_sigma: float, correlated: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Noisy depth as a scan of one point per sampled image column: ((N, 2) base-frame points,
        (N,) each point's range noise, m).

        A column's returns in the band lie on one vertical ray fan, so on a wall they measure one
        horizontal range: their mean, over the returns within 3 sigma of the column's median, has
        the noise sigma_w z^2 / sqrt(n / correlated) of n returns whose noise is correlated over
        `correlated` pixels. A cell average instead would spread one wall's noisy returns over
        several cells along each ray. Columns with fewer than `min_returns` such returns, or whose
        point's noise exceeds `max_sigma`, give no point."""
        cfg = self.config
        s = self._stride
        z = np.asarray(depth, dtype=np.float32)[::s, ::s]
        shape = z.shape
        dir_x, dir_y, dir_z = (d.reshape(shape) for d in (self._dir_x, self._dir_y, self._dir_z))
        valid = np.isfinite(z) & (z > 0)
        h = z * dir_z + self._origin[2]
        band = valid & (h >= cfg.min_height) & (h <= cfg.max_height)
        banded = np.where(band, z, np.float32(np.nan))
        have = band.any(axis=0)
        median = np.full(shape[1], np.nan, np.float32)
        median[have] = np.nanmedian(banded[:, have], axis=0)
        window = 3.0 * sigma_w * median * median
        inlier = band & (np.abs(z - median) <= window)
        count = inlier.sum(axis=0)
        n = np.maximum(count, 1)
        mean_z = np.where(inlier, z, 0).sum(axis=0) / n
        mean_x = np.where(inlier, dir_x, 0).sum(axis=0) / n
        mean_y = np.where(inlier, dir_y, 0).sum(axis=0) / n
        noise = sigma_w * mean_z * mean_z / np.sqrt(np.maximum(count / max(correlated, 1.0), 1.0))
        xy = np.column_stack([mean_z * mean_x + self._origin[0], mean_z * mean_y + self._origin[1]])
        r2 = np.einsum("ij,ij->i", xy, xy)
        keep = (count >= min_returns) & (noise <= max_sigma) & (r2 >= cfg.min_range**2) & (r2 <= cfg.max_range**2)
        return xy[keep].astype(np.float64), noise[keep].astype(np.float64)
