"""Map quality: a method's 2D occupancy grid against the world's ground-truth grid.

Precision: the fraction of the method's occupied cells that lie within a tolerance of an occupied
cell of the ground truth. A duplicated ("fake", "bifurcated") corridor puts walls where there are
none, and shows up as lost precision.

Recall: the fraction of the ground truth's occupied cells that the robot could have seen and that
have an occupied cell of the method's map within the tolerance. "Could have seen" is decided by
casting 2D rays over the ground-truth grid from the true trajectory, within the camera's
horizontal field of view and depth range (`observed_walls`): the first occupied cell on each ray
is seen. Without that mask, recall is over every occupied cell of the world.

The tolerance is `tolerance_cells` cells of the coarser of the two grids. The method's map is
first moved by the same transform (R, t, s) that aligned its trajectory ('none' by default).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from longslam.core.errors import InputError
from longslam.core.gridmap import OCCUPIED, GridMap
from longslam.eval.doubled_walls import doubled_walls
from longslam.eval.map_align import align_map


def transform_points(
    xy: np.ndarray,
    rotation: np.ndarray | None = None,
    translation: np.ndarray | None = None,
    scale: float = 1.0,
    height: float = 0.0,
) -> np.ndarray:
    """Apply x -> s R x + t (a 3D alignment) to floor points at `height`; returns (N, 2)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if rotation is None and translation is None and scale == 1.0:
        return xy
    rotation = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    translation = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
    points = np.column_stack([xy, np.full(len(xy), height)])
    return (scale * points @ rotation.T + translation)[:, :2]


def observed_walls(
    truth: GridMap,
    xyyaw: np.ndarray,
    hfov_deg: float = 90.0,
    max_range: float = 8.0,
    min_move: float = 0.5,
    min_turn_deg: float = 10.0,
    chunk: int = 32,
) -> np.ndarray:
    """Boolean mask over `truth.data`: occupied cells that a 2D ray from one of the poses hits first.

    Poses are taken every `min_move` metres or `min_turn_deg` degrees of the (N, 3) x, y, yaw path;
    from each, rays one cell apart at `max_range` fan over the horizontal field of view.
    """
    xyyaw = np.asarray(xyyaw, dtype=np.float64).reshape(-1, 3)
    if not (0 < hfov_deg < 360 and max_range > 0):
        raise InputError(f"need 0 < hfov_deg < 360 and max_range > 0, got {hfov_deg}, {max_range}")
    mask = np.zeros(truth.data.shape, dtype=bool)
    if not len(xyyaw):
        return mask
    keep = [0]
    for i in range(1, len(xyyaw)):
        last = xyyaw[keep[-1]]
        turned = abs(math.remainder(xyyaw[i, 2] - last[2], 2 * math.pi))
        if np.hypot(*(xyyaw[i, :2] - last[:2])) >= min_move or turned >= math.radians(min_turn_deg):
            keep.append(i)
    if keep[-1] != len(xyyaw) - 1:
        keep.append(len(xyyaw) - 1)
    poses = xyyaw[keep]

    res = truth.resolution
    half = math.radians(hfov_deg) / 2.0
    n_rays = int(math.ceil(2.0 * half * max_range / res)) + 1
    offsets = np.linspace(-half, half, n_rays)
    radii = np.arange(res / 2.0, max_range, res / 2.0)
    occupied = truth.data == OCCUPIED
    rows, cols = truth.data.shape
    ox, oy = truth.origin
    for start in range(0, len(poses), chunk):
        p = poses[start : start + chunk]
        angles = p[:, 2:3] + offsets[None, :]  # (P, R)
        x = p[:, 0, None, None] + np.cos(angles)[:, :, None] * radii[None, None, :]
        y = p[:, 1, None, None] + np.sin(angles)[:, :, None] * radii[None, None, :]
        col = np.floor((x - ox) / res).astype(np.int64)
        row = np.floor((y - oy) / res).astype(np.int64)
        inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        hit = np.zeros(row.shape, dtype=bool)
        hit[inside] = occupied[row[inside], col[inside]]
        first = np.argmax(hit, axis=2)  # (P, R)
        any_hit = hit.any(axis=2)
        pi, ri = np.nonzero(any_hit)
        si = first[pi, ri]
        mask[row[pi, ri, si], col[pi, ri, si]] = True
    return mask


def map_quality(estimate: GridMap, truth: GridMap, **options: Any) -> dict:
    """Precision, recall and F1 of the estimate's occupied cells against the truth's, as the map
    stands (no alignment of the map itself): `map_scores` without its `*_aligned` and doubled-wall
    keys, for the same keyword options (`tolerance_cells`, `observed`, the trajectory alignment
    `rotation`, `translation`, `scale` and the floor `height`).

    `observed` (a boolean mask over truth.data, e.g. from `observed_walls`) limits recall to the
    walls the robot could see. Precision is None when the estimate has no occupied cell, recall
    None when there is no (observed) occupied ground-truth cell.
    """
    return map_scores(estimate, truth, search_alignment=False, **options)


def _tolerance(estimate: GridMap, truth: GridMap, tolerance_cells: float, observed: np.ndarray | None) -> float:
    """The matching distance in metres, after checking the mask and the tolerance."""
    if observed is not None and np.shape(observed) != truth.data.shape:
        raise InputError(f"observed mask has shape {np.shape(observed)}, the ground-truth grid {truth.data.shape}")
    if tolerance_cells < 0:
        raise InputError(f"tolerance_cells must be >= 0, got {tolerance_cells}")
    return float(tolerance_cells) * max(estimate.resolution, truth.resolution)


def score_points(est_xy: np.ndarray, truth: GridMap, tolerance: float, observed: np.ndarray | None = None) -> dict:
    """`map_quality` of a map given as its (N, 2) occupied cell centres in the world, at a
    tolerance in metres."""
    # Cell centres of two grids can be up to half a cell apart even where they agree exactly.
    radius = tolerance + 1e-9
    true_mask = truth.data == OCCUPIED
    all_true_xy = truth.cell_to_world(np.argwhere(true_mask))
    seen_mask = true_mask if observed is None else true_mask & np.asarray(observed, dtype=bool)
    seen_xy = truth.cell_to_world(np.argwhere(seen_mask))

    precision = recall = None
    if len(est_xy) and len(all_true_xy):
        distance, _ = cKDTree(all_true_xy).query(est_xy, distance_upper_bound=radius)
        precision = float(np.mean(np.isfinite(distance)))
    elif len(est_xy):
        precision = 0.0
    if len(seen_xy):
        if len(est_xy):
            distance, _ = cKDTree(est_xy).query(seen_xy, distance_upper_bound=radius)
            recall = float(np.mean(np.isfinite(distance)))
        else:
            recall = 0.0
    f1 = None
    if precision is not None and recall is not None:
        f1 = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    return {
        "map_precision": precision,
        "map_recall": recall,
        "map_f1": f1,
        "map_tolerance_m": tolerance,
        "map_occupied_cells": int(len(est_xy)),
        "map_true_cells": int(len(seen_xy)),
    }


def map_scores(
    estimate: GridMap,
    truth: GridMap,
    tolerance_cells: float = 2.0,
    observed: np.ndarray | None = None,
    rotation: np.ndarray | None = None,
    translation: np.ndarray | None = None,
    scale: float = 1.0,
    height: float = 0.0,
    with_places: bool = False,
    search_alignment: bool = True,
) -> dict:
    """`map_quality` as it is (after the trajectory's alignment, if any), again after the map's
    best planar alignment to the truth (`map_align`: keys `*_aligned`, the alignment itself in
    `map_alignment` as [x m, y m, yaw deg]), and the share of observed true walls the aligned map
    shows twice (`map_doubled_walls`, see `doubled_walls`). A global drift lowers only the
    unaligned score; doubled walls ("fake corridors") lower the aligned one and raise the share.
    With `with_places`, `map_doubled_places` holds the (K, 2) world x, y of the doubled walls;
    without `search_alignment`, only the scores as the map stands (`map_quality`)."""

    tolerance = _tolerance(estimate, truth, tolerance_cells, observed)
    walls = transform_points(estimate.occupied_points(), rotation, translation, scale, height)
    scores = score_points(walls, truth, tolerance, observed)
    if not search_alignment:
        return scores
    # The search and the doubled-wall test need a tolerance of at least a truth cell.
    search = max(tolerance, truth.resolution)
    planar = align_map(walls, truth, search)
    aligned_walls = planar.apply(walls)
    aligned = score_points(aligned_walls, truth, tolerance, observed)
    share, places = doubled_walls(aligned_walls, truth, observed, search)
    scores.update(
        {
            "map_precision_aligned": aligned["map_precision"],
            "map_recall_aligned": aligned["map_recall"],
            "map_f1_aligned": aligned["map_f1"],
            "map_alignment": [planar.x, planar.y, math.degrees(planar.yaw)],
            "map_doubled_walls": share,
            "map_doubled_wall_cells": int(len(places)),
        }
    )
    if with_places:
        scores["map_doubled_places"] = places
    return scores
