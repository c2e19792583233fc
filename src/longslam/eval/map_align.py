"""The best planar (x, y, yaw) alignment of a method's occupancy map to the ground-truth map.

A map that drifted as a whole (the trajectory's global error) is harmless for navigation; a map
with doubled walls is not. Scoring the map once as it is and once after this alignment tells the
two apart: drift loses only the unaligned score, damage loses both.

The search is global, then local. Globally: for each yaw on a grid of `yaw_step_deg`, the map's
occupied cells, rotated, are rasterised at `coarse` metres and cross-correlated (FFT) with the
ground truth's occupied cells dilated by the tolerance: the peak is the translation that puts
the most of the map's walls on true walls. Locally: trimmed point-to-point ICP from the best
(x, y, yaw), each step the closed-form planar rigid fit of the pairs within the tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sp_fft
from scipy import ndimage
from scipy.spatial import cKDTree

from longslam.core.errors import InputError
from longslam.core.geometry.fit import rigid_transform_2d
from longslam.core.gridmap import GridMap


@dataclass(frozen=True)
class PlanarAlignment:
    x: float
    y: float
    yaw: float  # radians
    inliers: float  # share of the map's occupied cells within the tolerance of a true wall, aligned

    def apply(self, xy: np.ndarray) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return xy @ np.array([[c, -s], [s, c]]).T + (self.x, self.y)


IDENTITY = PlanarAlignment(0.0, 0.0, 0.0, 0.0)


def _rotate(xy: np.ndarray, yaw: float, about: np.ndarray) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return (xy - about) @ np.array([[c, -s], [s, c]]).T + about


class _FullConvolution:
    """`scipy.signal.fftconvolve(target, kernel, mode="full")` for one target and many kernels,
    to the bit: the same padded FFT sizes, and the target's spectrum kept per size. (It also
    spares each run the 0.5 s import of scipy.signal.)"""

    def __init__(self, target: np.ndarray):
        self.target = target
        self._spectra: dict[tuple[int, int], np.ndarray] = {}

    def convolve(self, kernel: np.ndarray) -> np.ndarray:
        shape = tuple(a + b - 1 for a, b in zip(self.target.shape, kernel.shape))
        padded = tuple(sp_fft.next_fast_len(n, True) for n in shape)
        spectrum = self._spectra.get(padded)
        if spectrum is None:
            spectrum = self._spectra[padded] = sp_fft.rfftn(self.target, padded)
        full = sp_fft.irfftn(spectrum * sp_fft.rfftn(kernel, padded), padded)
        return full[: shape[0], : shape[1]].copy()


def align_map(
    points: np.ndarray,
    truth: GridMap,
    tolerance: float,
    max_yaw_deg: float = 20.0,
    yaw_step_deg: float = 1.0,
    coarse: float = 0.2,
    iterations: int = 30,
) -> PlanarAlignment:
    """The (x, y, yaw) that moves a map's occupied cell centres (`points`, (N, 2) world x, y) onto
    the truth's occupied cells: x -> R x + t.

    Yaw is searched within +-`max_yaw_deg` (about the centre of the map's walls); translation
    without bound. Returns the identity (with inliers 0) when either map has no occupied cell."""
    if tolerance <= 0 or coarse <= 0 or yaw_step_deg <= 0 or max_yaw_deg < 0:
        raise InputError(
            f"align_map needs tolerance > 0, coarse > 0, yaw_step_deg > 0 and max_yaw_deg >= 0; "
            f"got {tolerance}, {coarse}, {yaw_step_deg}, {max_yaw_deg}"
        )
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    walls = truth.occupied_points()
    if not len(points) or not len(walls):
        return IDENTITY
    centre = points.mean(axis=0)

    # The truth's walls, dilated by the tolerance, as a coarse raster.
    lo = walls.min(axis=0) - tolerance - coarse
    shape = (np.ceil((walls.max(axis=0) + tolerance + coarse - lo) / coarse).astype(int) + 1)[::-1]
    target = np.zeros(shape, np.float32)
    idx = np.floor((walls - lo) / coarse).astype(int)
    target[idx[:, 1], idx[:, 0]] = 1.0
    grow = int(math.ceil(tolerance / coarse))
    if grow:
        target = ndimage.binary_dilation(target > 0, iterations=grow).astype(np.float32)

    spectra = _FullConvolution(target)
    best = (-1.0, 0.0, np.zeros(2))
    yaws = np.deg2rad(np.arange(-max_yaw_deg, max_yaw_deg + 1e-9, yaw_step_deg))
    for yaw in yaws:
        moved = _rotate(points, yaw, centre)
        mlo = moved.min(axis=0)
        midx = np.floor((moved - mlo) / coarse).astype(int)
        source = np.zeros((midx[:, 1].max() + 1, midx[:, 0].max() + 1), np.float32)
        np.add.at(source, (midx[:, 1], midx[:, 0]), 1.0)
        # score[r, c]: the map's cells that land on walls when its raster's corner goes to
        # target cell (r - rows_s + 1, c - cols_s + 1).
        score = spectra.convolve(source[::-1, ::-1])
        r, c = np.unravel_index(int(np.argmax(score)), score.shape)
        if score[r, c] > best[0]:
            shift_cells = np.array([c - source.shape[1] + 1, r - source.shape[0] + 1])
            best = (float(score[r, c]), float(yaw), lo + shift_cells * coarse - mlo)

    # Local refinement: trimmed ICP at full resolution from the coarse optimum.
    _, yaw, shift = best
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    translation = centre - rotation @ centre + shift
    tree = cKDTree(walls)
    gate = max(2.0 * tolerance, coarse)
    for _ in range(iterations):
        moved = points @ rotation.T + translation
        distance, nearest = tree.query(moved, distance_upper_bound=gate)
        pairs = np.isfinite(distance)
        if pairs.sum() < 3:
            break
        step_r, step_t = rigid_transform_2d(moved[pairs], walls[nearest[pairs]])
        rotation, translation = step_r @ rotation, step_r @ translation + step_t
        if np.linalg.norm(step_t) < 1e-4 and abs(math.atan2(step_r[1, 0], step_r[0, 0])) < 1e-5:
            break
    # ICP minimises squared distances, the score counts points within the tolerance: keep
    # whichever of the start, the coarse optimum and the ICP result scores best.
    coarse_rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    candidates = [
        (np.eye(2), np.zeros(2)),
        (coarse_rotation, centre - coarse_rotation @ centre + shift),
        (rotation, translation),
    ]
    best_share, best_fit = -1.0, candidates[0]
    for rot, trans in candidates:
        distance, _ = tree.query(points @ rot.T + trans, distance_upper_bound=tolerance + 1e-9)
        share = float(np.mean(np.isfinite(distance)))
        if share > best_share + 1e-12:
            best_share, best_fit = share, (rot, trans)
    rotation, translation = best_fit
    return PlanarAlignment(
        float(translation[0]), float(translation[1]), float(math.atan2(rotation[1, 0], rotation[0, 0])), best_share
    )
