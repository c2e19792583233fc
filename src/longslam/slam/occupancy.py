"""2D occupancy from depth images, built the way RTAB-Map builds its grid.

Each keyframe keeps a small `LocalGrid` (obstacle and free cells in the robot's floor frame),
and the global map is re-assembled from all local grids at their latest optimised poses. Keeping
per-keyframe cells instead of one global raster is what lets a loop closure move the map with
the trajectory; storing them as int16 cell pairs keeps thousands of keyframes small.

Defaults follow RTAB-Map: Grid/CellSize 0.05 m, Grid/RangeMax 5 m, obstacles from points
0.2-1.5 m above the floor, free space by ray tracing from the robot to the observed points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.errors import InputError
from longslam.frame import Intrinsics
from longslam.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap


@dataclass
class LocalGrid:
    """Cells seen from one keyframe, as integer (i, j) = floor((x, y) / cell) in the robot's
    floor frame (x forward, y left, origin under the robot)."""

    obstacles: np.ndarray  # (N, 2) int16 (int32 for very fine cells), unique
    free: np.ndarray  # (M, 2) int16, unique, disjoint from obstacles
    cell: float

    @property
    def nbytes(self) -> int:
        return int(self.obstacles.nbytes + self.free.nbytes)

    def obstacle_points(self) -> np.ndarray:
        """(N, 2) float x, y of the obstacle cell centres in the robot frame."""
        return (self.obstacles.astype(np.float64) + 0.5) * self.cell

    def free_points(self) -> np.ndarray:
        return (self.free.astype(np.float64) + 0.5) * self.cell


def _empty_cells() -> np.ndarray:
    return np.zeros((0, 2), dtype=np.int16)


def _unique_cells(cells: np.ndarray) -> np.ndarray:
    if not len(cells):
        return _empty_cells()
    # Unique on one int64 key per cell: much faster than np.unique(axis=0) on rows.
    cells = cells.astype(np.int64)
    keys = np.unique((cells[:, 0] << 32) + (cells[:, 1] & 0xFFFFFFFF))
    cells = np.column_stack([keys >> 32, (keys & 0xFFFFFFFF).astype(np.uint32).astype(np.int32)])
    # int16 covers +-1.6 km at 5 cm; fall back to int32 only for unusually fine cells.
    small = np.abs(cells).max() < np.iinfo(np.int16).max
    return cells.astype(np.int16 if small else np.int32)


def _remove_cells(cells: np.ndarray, drop: np.ndarray) -> np.ndarray:
    """Rows of `cells` not in `drop` (both small int arrays), via 1D keys."""
    if not len(cells) or not len(drop):
        return cells
    key = lambda c: (c[:, 0].astype(np.int64) << 32) + (c[:, 1].astype(np.int64) & 0xFFFFFFFF)  # noqa: E731
    return cells[~np.isin(key(cells), key(drop))]


def depth_points_in_base(
    depth: np.ndarray, intrinsics: Intrinsics, camera_in_base: np.ndarray, stride: int = 2
) -> np.ndarray:
    """Back-project every `stride`-th pixel with a return into the robot's floor frame: (N, 3)."""
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise InputError(f"depth must be a (H, W) array, got shape {depth.shape}")
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise InputError(
            f"depth shape {depth.shape} does not match intrinsics {intrinsics.height}x{intrinsics.width} (H x W)"
        )
    stride = max(int(stride), 1)
    sub = depth[::stride, ::stride].astype(np.float64)
    v, u = np.mgrid[0:depth.shape[0]:stride, 0:depth.shape[1]:stride]
    ok = np.isfinite(sub) & (sub > 0)
    z = sub[ok]
    x = (u[ok] - intrinsics.cx) / intrinsics.fx * z
    y = (v[ok] - intrinsics.cy) / intrinsics.fy * z
    pose = np.asarray(camera_in_base, dtype=np.float64)
    return np.column_stack([x, y, z]) @ pose[:3, :3].T + pose[:3, 3]


def _trace_free(ends: np.ndarray, cell: float) -> np.ndarray:
    """Cells crossed by 2D rays from the origin to each end point, (K, 2) int.

    Rays are sampled every half cell, all at once: one ragged array of sample positions built
    with np.repeat, rather than a Python loop per ray.
    """
    if not len(ends):
        return _empty_cells()
    lengths = np.linalg.norm(ends, axis=1)
    counts = np.ceil(lengths / (0.5 * cell)).astype(np.int64) + 1
    ray = np.repeat(np.arange(len(ends)), counts)
    starts = np.cumsum(counts) - counts
    step = np.arange(len(ray)) - np.repeat(starts, counts)
    t = step / np.maximum(np.repeat(counts, counts) - 1, 1)
    samples = ends[ray] * t[:, None]
    return np.floor(samples / cell).astype(np.int64)


def local_grid(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    camera_in_base: np.ndarray,
    cell: float = 0.05,
    range_max: float = 5.0,
    min_height: float = 0.2,
    max_height: float = 1.5,
    stride: int = 2,
) -> LocalGrid:
    """Obstacle and free cells seen in one depth image, in the robot's floor frame.

    Points between `min_height` and `max_height` within `range_max` (horizontal distance) are
    obstacles. Points below `min_height` are floor: the floor cell and the ray to it are free,
    and floor seen beyond `range_max` still clears the ray up to `range_max`. Points above
    `max_height` (ceiling, tall shelves) say nothing about the obstacle band and are ignored.
    A cell that holds an obstacle is never also free in the same image.
    """
    if cell <= 0 or range_max <= 0 or max_height <= min_height:
        raise InputError(
            f"need cell > 0, range_max > 0 and max_height > min_height; got cell={cell}, "
            f"range_max={range_max}, min_height={min_height}, max_height={max_height}"
        )
    pts = depth_points_in_base(depth, intrinsics, camera_in_base, stride)
    if not len(pts):
        return LocalGrid(_empty_cells(), _empty_cells(), float(cell))
    xy = pts[:, :2]
    dist = np.linalg.norm(xy, axis=1)
    in_range = dist <= range_max
    obstacle = in_range & (pts[:, 2] >= min_height) & (pts[:, 2] <= max_height)
    floor = pts[:, 2] < min_height

    obstacles = _unique_cells(np.floor(xy[obstacle] / cell).astype(np.int64))
    floor_xy = xy[floor]
    floor_dist = dist[floor]
    far = floor_dist > range_max
    floor_xy[far] *= (range_max / floor_dist[far])[:, None]
    floor_cells = np.floor(floor_xy / cell).astype(np.int64)
    # Floor cells are free themselves; for the space between robot and floor one ray per
    # angular sector (a cell wide at range_max) to the farthest floor point covers the same
    # cells as a ray per point, for a small fraction of the samples. Obstacles are few, so
    # each obstacle cell gets its own ray.
    ends = [(obstacles.astype(np.float64) + 0.5) * cell]
    if len(floor_xy):
        n_bins = int(np.ceil(2.0 * np.pi * range_max / cell))
        angle = np.arctan2(floor_xy[:, 1], floor_xy[:, 0])
        sector = np.minimum(((angle + np.pi) / (2.0 * np.pi) * n_bins).astype(np.int64), n_bins - 1)
        order = np.lexsort((-np.minimum(floor_dist, range_max), sector))
        first = np.ones(len(order), dtype=bool)
        first[1:] = sector[order][1:] != sector[order][:-1]
        ends.append(floor_xy[order[first]])
    traced = _trace_free(np.vstack(ends), cell)
    free = _unique_cells(np.vstack([traced, floor_cells]))
    free = _remove_cells(free, obstacles)
    return LocalGrid(obstacles, free, float(cell))


def _cells_to_world(cells: list[np.ndarray], poses: np.ndarray, cell: float) -> np.ndarray:
    """Centres of every local grid's cells moved to the world by that grid's pose: (K, 2)."""
    counts = np.array([len(c) for c in cells], dtype=np.int64)
    if not counts.sum():
        return np.zeros((0, 2))
    local = (np.vstack(cells).astype(np.float64) + 0.5) * cell
    pose = np.repeat(poses, counts, axis=0)
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    x = pose[:, 0] + c * local[:, 0] - s * local[:, 1]
    y = pose[:, 1] + s * local[:, 0] + c * local[:, 1]
    return np.column_stack([x, y])


def assemble(local_grids: list[LocalGrid], poses_xyyaw: np.ndarray, cell: float = 0.05) -> GridMap:
    """Fuse local grids placed at their planar world poses into one GridMap.

    Every placement votes: an obstacle cell is a hit, a free cell a miss. A world cell is
    occupied when its hits outnumber its misses, free when it was seen and not occupied, and
    unknown when never seen. Voting, rather than last-writer-wins, lets many views outvote a
    spurious obstacle (a person walking by, a depth artefact).
    """
    poses = np.asarray(poses_xyyaw, dtype=np.float64).reshape(-1, 3)
    if len(poses) != len(local_grids):
        raise InputError(f"assemble: {len(local_grids)} local grids but {len(poses)} poses")
    hits_xy = _cells_to_world([g.obstacles for g in local_grids], poses, cell)
    miss_xy = _cells_to_world([g.free for g in local_grids], poses, cell)
    all_xy = np.vstack([hits_xy, miss_xy])
    if not len(all_xy):
        return GridMap(np.full((1, 1), UNKNOWN, dtype=np.int8), float(cell), (0.0, 0.0))

    # Snap the origin to the cell lattice so a map assembled twice lines up cell for cell.
    lo = np.floor(all_xy.min(axis=0) / cell) - 1
    hi = np.floor(all_xy.max(axis=0) / cell) + 1
    cols, rows = (hi - lo + 1).astype(np.int64)
    origin = (float(lo[0] * cell), float(lo[1] * cell))

    def votes(xy: np.ndarray) -> np.ndarray:
        idx = np.floor(xy / cell).astype(np.int64) - lo.astype(np.int64)
        flat = idx[:, 1] * cols + idx[:, 0]
        return np.bincount(flat, minlength=rows * cols).reshape(rows, cols)

    hits, misses = votes(hits_xy), votes(miss_xy)
    data = np.full((rows, cols), UNKNOWN, dtype=np.int8)
    data[(misses > 0) | (hits > 0)] = FREE
    data[hits > misses] = OCCUPIED
    return GridMap(data, float(cell), origin)
