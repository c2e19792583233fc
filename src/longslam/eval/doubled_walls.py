"""Doubled walls: the "fake corridor" damage of a map, as a share of the true walls.

A map whose trajectory broke in two (a missed loop closure, a bad one) draws the same wall twice,
a corridor width apart: two parallel wall runs where the building has one. For each observed true
wall cell, with its wall's direction, the map (already aligned to the truth, `map_align`) is read
along a short run parallel to the wall at offsets across it. A wall is shown where at least
`support` of the run's samples have a map wall within the tolerance; the true wall is shown twice
when the map shows it in place (within the tolerance) and again, past a stretch without map
walls, at an offset between `min_gap` and `max_gap` where the truth has no wall.

Offsets and runs are sampled on the truth's grid, through distance transforms of the two maps, so
the cost is a few array look-ups per sample, done in chunks of wall cells.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from longslam.core.errors import InputError
from longslam.core.gridmap import OCCUPIED, GridMap


def wall_normals(truth: GridMap, cells: np.ndarray, smooth_cells: float = 2.0) -> np.ndarray:
    """(C, 2) unit normals (x, y) of the truth's walls at its (C, 2) row, column `cells`: the
    gradient of the occupied mask, smoothed; zero where undefined."""
    occupied = (truth.data == OCCUPIED).astype(np.float64)
    blurred = ndimage.gaussian_filter(occupied, smooth_cells)
    gy, gx = np.gradient(blurred)
    g = np.column_stack([gx[cells[:, 0], cells[:, 1]], gy[cells[:, 0], cells[:, 1]]])
    norm = np.hypot(g[:, 0], g[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm[:, None] > 1e-9, g / norm[:, None], 0.0)


def _near(mask: np.ndarray, radius_cells: float) -> np.ndarray:
    """Cells within `radius_cells` (Euclidean, centre to centre) of a True cell of `mask`: a
    dilation by the disk of that radius, what thresholding the distance transform gives, at a
    tenth of its time for the few cells of a tolerance."""
    reach = int(np.floor(radius_cells + 1e-9))
    di, dj = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    disk = np.sqrt(di * di + dj * dj) <= radius_cells + 1e-9
    return ndimage.binary_dilation(mask, structure=disk)


def _unexplained_run(run: np.ndarray, explained: np.ndarray, far: np.ndarray) -> np.ndarray:
    """Per row of `run` (C, K: map wall support at offsets going outwards from a true wall):
    is there a run of offsets with map support, after at least one offset without (one wall
    drawn thick is not two walls), that starts at a `far` offset and where the truth has no wall
    at any of its offsets (a wall drawn a cell off is the true wall, not a second one)?"""
    rows = run.shape[0]
    gap = np.zeros(rows, bool)  # an offset without map support seen since the wall in place
    inside = np.zeros(rows, bool)  # within a run of support that started after a gap
    candidate = np.zeros(rows, bool)  # that run started far enough out
    clean = np.zeros(rows, bool)  # ... and no offset of it has a true wall
    found = np.zeros(rows, bool)
    for k in range(run.shape[1]):
        starts = run[:, k] & ~inside & gap
        inside = np.where(starts, True, inside & run[:, k])
        candidate = np.where(starts, far[k], candidate)
        clean = np.where(starts, True, clean) & ~explained[:, k]
        ends = ~run[:, k]
        found |= ends & candidate & clean & ~inside & gap
        candidate &= inside
        gap |= ends
    return found | (inside & candidate & clean)


def rasterise(xy: np.ndarray, like: GridMap) -> np.ndarray:
    """Boolean mask over `like`'s cells holding any of the (N, 2) world points."""
    mask = np.zeros(like.data.shape, bool)
    rc = like.world_to_cell(xy)
    ok = like.inside(rc)
    mask[rc[ok, 0], rc[ok, 1]] = True
    return mask


def doubled_walls(
    map_walls: np.ndarray,
    truth: GridMap,
    observed: np.ndarray | None,
    tolerance: float,
    min_gap: float = 0.5,
    max_gap: float = 3.0,
    run_length: float = 1.0,
    support: float = 0.5,
    chunk: int = 2048,
) -> tuple[float | None, np.ndarray]:
    """(share of the observed true wall cells the map shows twice, (K, 2) world x, y of those cells).

    `map_walls` (N, 2) are the map's occupied cell centres, already aligned to the truth. The
    share is None when there is no observed true wall cell."""
    if not (tolerance > 0 and 0 < min_gap < max_gap and run_length > 0 and 0 < support <= 1):
        raise InputError(
            f"doubled_walls needs tolerance > 0, 0 < min_gap < max_gap, run_length > 0 and 0 < support <= 1; "
            f"got tolerance={tolerance}, min_gap={min_gap}, max_gap={max_gap}, run_length={run_length}, "
            f"support={support}"
        )
    true_walls = truth.data == OCCUPIED
    if observed is not None:
        if np.shape(observed) != truth.data.shape:
            raise InputError(f"observed mask has shape {np.shape(observed)}, the ground-truth grid {truth.data.shape}")
        cells = np.argwhere(true_walls & np.asarray(observed, bool))
    else:
        cells = np.argwhere(true_walls)
    if not len(cells):
        return None, np.zeros((0, 2))
    res = truth.resolution
    radius = tolerance / res
    map_near = _near(rasterise(map_walls, truth), radius)
    truth_near = _near(true_walls, radius)
    normals = wall_normals(truth, cells)

    offsets = np.arange(-max_gap, max_gap + 1e-9, res)  # across the wall, metres
    along = np.arange(-run_length / 2, run_length / 2 + 1e-9, res)
    in_place = np.abs(offsets) <= tolerance + 1e-9
    rows, cols = truth.data.shape
    # Looked up by flat index, with one extra False cell that every sample off the grid reads.
    off_grid = rows * cols
    map_flat = np.append(map_near.ravel(), False)
    truth_flat = np.append(truth_near.ravel(), False)
    doubled = np.zeros(len(cells), bool)
    for start in range(0, len(cells), chunk):
        rc = cells[start : start + chunk]
        cx, cy = truth.cell_to_world(rc).T  # (C,) each
        nx, ny = normals[start : start + chunk].T
        tx, ty = -ny, nx
        # Sample points (C, offsets, along), per coordinate.
        x = (cx[:, None, None] + offsets[None, :, None] * nx[:, None, None]) + along[None, None, :] * tx[:, None, None]
        y = (cy[:, None, None] + offsets[None, :, None] * ny[:, None, None]) + along[None, None, :] * ty[:, None, None]
        col = np.floor((x - truth.origin[0]) / res).astype(np.int64)
        row = np.floor((y - truth.origin[1]) / res).astype(np.int64)
        inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        flat = np.where(inside, row * cols + col, off_grid)
        map_run = np.count_nonzero(map_flat[flat], axis=2) / len(along) >= support  # (C, offsets)
        true_run = truth_flat[flat].any(axis=2)
        shown = map_run[:, in_place].any(axis=1)
        fake = np.zeros(len(rc), bool)
        for side in (offsets > tolerance, offsets < -tolerance):
            order = np.flatnonzero(side)
            order = order[np.argsort(np.abs(offsets[order]))]  # outwards from the wall
            fake |= _unexplained_run(map_run[:, order], true_run[:, order], np.abs(offsets[order]) >= min_gap)
        defined = (nx != 0) | (ny != 0)
        doubled[start : start + chunk] = shown & fake & defined
    return float(doubled.mean()), truth.cell_to_world(cells[doubled])
