"""2D occupancy from depth images, built the way RTAB-Map builds its grid.

Each keyframe keeps a small `LocalGrid` (obstacle and free cells in the robot's floor frame),
and the global map is re-assembled from all local grids at their latest optimised poses. Keeping
per-keyframe cells instead of one global raster is what lets a loop closure move the map with
the trajectory; storing them as int16 cell pairs keeps thousands of keyframes small.

Defaults follow RTAB-Map: Grid/CellSize 0.05 m, obstacles from points 0.2-1.5 m above the floor,
free space by ray tracing from the robot to the observed points, local grids fused with RTAB-Map's
global occupancy log-odds. Two departures: every depth pixel is used (no decimation), and the range
is the camera's (8 m) rather than Grid/RangeMax's 5 m, so that every wall seen is mapped.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.geometry.cells import box_is_dense, group_cells_2d
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap


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
    i, j, _ = group_cells_2d(cells[:, 0], cells[:, 1])
    cells = np.column_stack([i, j])
    # int16 covers +-1.6 km at 5 cm; fall back to int32 only for unusually fine cells.
    small = np.abs(cells).max() < np.iinfo(np.int16).max
    return cells.astype(np.int16 if small else np.int32)


def _remove_cells(cells: np.ndarray, drop: np.ndarray) -> np.ndarray:
    """Rows of `cells` not in `drop` (both small int arrays): by a presence array over the box
    both lie in, or by sorted 1D keys when that box is mostly empty."""
    if not len(cells) or not len(drop):
        return cells
    i, j = cells[:, 0].astype(np.int64), cells[:, 1].astype(np.int64)
    di, dj = drop[:, 0].astype(np.int64), drop[:, 1].astype(np.int64)
    i_low, j_low = min(int(i.min()), int(di.min())), min(int(j.min()), int(dj.min()))
    rows = max(int(i.max()), int(di.max())) - i_low + 1
    cols = max(int(j.max()), int(dj.max())) - j_low + 1
    if not box_is_dense(rows * cols, len(cells) + len(drop)):
        key = lambda a, b: (a << 32) + (b & 0xFFFFFFFF)  # noqa: E731
        return cells[~np.isin(key(i, j), key(di, dj))]
    dropped = np.zeros(rows * cols, bool)
    dropped[(di - i_low) * cols + (dj - j_low)] = True
    return cells[~dropped[(i - i_low) * cols + (j - j_low)]]


@functools.lru_cache(maxsize=8)
def _pixel_rays(intrinsics: Intrinsics, stride: int, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel of a `stride`-subsampled image, (u - cx) / fx and (v - cy) / fy: a point's x and
    y over its depth. The same for every image of a camera, so computed once."""
    rows, cols = np.indices(shape)
    return (cols * stride - intrinsics.cx) / intrinsics.fx, (rows * stride - intrinsics.cy) / intrinsics.fy


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
    sub = depth[::stride, ::stride]
    ok = np.isfinite(sub) & (sub > 0)
    z = sub[ok].astype(np.float64)
    along_x, along_y = _pixel_rays(intrinsics, stride, sub.shape)
    x = along_x[ok] * z
    y = along_y[ok] * z
    # The rotation applied per coordinate: a (N, 3) @ (3, 3) product is slower for N ~ 77k.
    pose = np.asarray(camera_in_base, dtype=np.float64)
    rot, t = pose[:3, :3], pose[:3, 3]
    out = np.empty((len(z), 3))
    for axis in range(3):
        out[:, axis] = rot[axis, 0] * x + rot[axis, 1] * y + rot[axis, 2] * z + t[axis]
    return out


def _trace_free(ends: np.ndarray, cell: float) -> np.ndarray:
    """Cells crossed by 2D rays from the origin to each end point, (K, 2) int.

    Rays are sampled every half cell, all at once: one ragged array of sample positions built
    with np.repeat, rather than a Python loop per ray. A sample in the same cell as the one
    before it is dropped (most are: two samples a cell), which leaves the set of cells as it was.
    """
    if not len(ends):
        return _empty_cells()
    lengths = np.linalg.norm(ends, axis=1)
    counts = np.ceil(lengths / (0.5 * cell)).astype(np.int64) + 1
    starts = np.cumsum(counts) - counts
    step = np.arange(int(counts.sum())) - np.repeat(starts, counts)
    t = step / np.maximum(np.repeat(counts, counts) - 1, 1)
    # Per axis: no (K, 2) copies of the samples.
    i = np.floor(np.repeat(ends[:, 0], counts) * t / cell).astype(np.int64)
    j = np.floor(np.repeat(ends[:, 1], counts) * t / cell).astype(np.int64)
    new = np.ones(len(i), dtype=bool)
    new[1:] = (i[1:] != i[:-1]) | (j[1:] != j[:-1])
    return np.column_stack([i[new], j[new]])


def local_grid(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    camera_in_base: np.ndarray,
    cell: float = 0.05,
    range_max: float = 8.0,
    min_height: float = 0.2,
    max_height: float = 1.5,
    stride: int = 1,
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
    dist = np.hypot(xy[:, 0], xy[:, 1])
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
        # Each sector's farthest point, the first of the sector's points at that distance (a
        # stable sort by sector and distance would pick the same), sectors in ascending order:
        # per-sector maxima cost one pass where the sort of every floor point cost most of a grid.
        reach = np.minimum(floor_dist, range_max)
        farthest = np.full(n_bins, -np.inf)
        np.maximum.at(farthest, sector, reach)
        candidates = np.flatnonzero(reach == farthest[sector])
        first = np.full(n_bins, len(reach))
        np.minimum.at(first, sector[candidates], candidates)
        ends.append(floor_xy[first[first < len(reach)]])
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


def logodds(probability: float) -> float:
    return float(np.log(probability / (1.0 - probability)))


class GridVotes:
    """Local grids placed at their planar world poses, fused into one world grid a grid at a time.

    Every placement updates each cell it touches by an occupancy log-odds, as RTAB-Map's global
    grid does (GridGlobal/ProbHit 0.7, ProbMiss 0.4, clamped to 0.1192..0.971): an obstacle cell
    is a hit, a free cell a miss, and a cell is occupied when its log-odds is above 0 (probability
    0.5). A hit outweighs about two misses, so rays from nodes that graze a wall, or that saw the
    floor at its foot from a pose a few centimetres off, do not erase it; a spurious obstacle seen
    once is still cleared by the views that saw through it. Clamping keeps a cell seen a thousand
    times able to change. A cell is free when seen and not occupied, unknown when never seen.
    Only the log-odds array is held (it grows as the grids reach further), so a kilometre of
    keyframes can be streamed from long-term memory instead of held at once.
    """

    GROW_CELLS = 256  # margin added whenever the arrays must grow, so they grow seldom

    def __init__(
        self,
        cell: float = 0.05,
        prob_hit: float = 0.7,
        prob_miss: float = 0.4,
        clamp_min: float = 0.1192,
        clamp_max: float = 0.971,
    ):
        if not (0.5 < prob_hit < 1.0 and 0.0 < prob_miss < 0.5 and 0.0 < clamp_min < 0.5 < clamp_max < 1.0):
            raise InputError(
                f"occupancy probabilities need 0.5 < prob_hit < 1, 0 < prob_miss < 0.5 and "
                f"0 < clamp_min < 0.5 < clamp_max < 1; got prob_hit={prob_hit}, prob_miss={prob_miss}, "
                f"clamp_min={clamp_min}, clamp_max={clamp_max}"
            )
        self.cell = float(cell)
        self.hit, self.miss = logodds(prob_hit), logodds(prob_miss)
        self.lo_clamp, self.hi_clamp = logodds(clamp_min), logodds(clamp_max)
        self._lo: np.ndarray | None = None  # world cell index (col, row) of [0, 0]
        # NaN: never seen. float32 halves the bytes of the former pair of int32 counts.
        self._odds = np.zeros((0, 0), np.float32)

    @property
    def nbytes(self) -> int:
        return int(self._odds.nbytes)

    def _cells(self, cells: np.ndarray, pose: np.ndarray) -> np.ndarray:
        return np.floor(_cells_to_world([cells], pose[None], self.cell) / self.cell).astype(np.int64)

    def _cover(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Grow the array (with a margin) so that world cells lo..hi (inclusive) fit."""
        margin = self.GROW_CELLS
        if self._lo is None:
            lo, hi = lo - margin, hi + margin
        else:
            old_hi = self._lo + np.array(self._odds.shape[::-1]) - 1
            # Cells must fit with one cell to spare all round: `grid` crops a border of one
            # unknown cell around the cells seen (a grid reaching the array's very edge once
            # cropped from row -1, an empty grid).
            if np.all(lo - 1 >= self._lo) and np.all(hi + 1 <= old_hi):
                return
            # A margin only on the sides that grow: margins must not pile up on the others.
            lo = np.where(lo - 1 < self._lo, lo - margin, self._lo)
            hi = np.where(hi + 1 > old_hi, hi + margin, old_hi)
        cols, rows = (hi - lo + 1).astype(np.int64)
        odds = np.full((rows, cols), np.nan, np.float32)
        if self._lo is not None:
            r0, c0 = (self._lo - lo)[::-1]
            h, w = self._odds.shape
            odds[r0 : r0 + h, c0 : c0 + w] = self._odds
        self._lo, self._odds = lo, odds

    def reserve(self, lo_xy: np.ndarray, hi_xy: np.ndarray) -> None:
        """Allocate the array for world x, y in lo_xy..hi_xy (metres) at once, before any grid is
        added: growing it as grids come holds the old array beside the new one. Grids reaching
        beyond still grow it; the fused grid is the same either way."""
        if self._lo is not None:
            raise RuntimeError("GridVotes.reserve must come before the first add")
        lo = np.floor(np.asarray(lo_xy, dtype=np.float64) / self.cell).astype(np.int64) - 1
        hi = np.floor(np.asarray(hi_xy, dtype=np.float64) / self.cell).astype(np.int64) + 1
        cols, rows = (hi - lo + 1).astype(np.int64)
        self._lo, self._odds = lo, np.full((rows, cols), np.nan, np.float32)

    def add(self, grid: LocalGrid, pose_xyyaw) -> None:
        pose = np.asarray(pose_xyyaw, dtype=np.float64).reshape(3)
        hit_cells, miss_cells = self._cells(grid.obstacles, pose), self._cells(grid.free, pose)
        both = np.vstack([hit_cells, miss_cells])
        if not len(both):
            return
        lo, hi = both.min(axis=0), both.max(axis=0)
        self._cover(lo, hi)
        assert self._lo is not None  # `_cover` placed the array
        cols = self._odds.shape[1]
        # One update per cell and node (two local cells can land in one world cell once
        # rotated); a cell that is both a hit and a miss of this node is a hit.
        row0, col0 = int(self._lo[1]), int(self._lo[0])
        hits, misses = _hits_and_misses(
            (hit_cells[:, 1] - row0) * cols + (hit_cells[:, 0] - col0),
            (miss_cells[:, 1] - row0) * cols + (miss_cells[:, 0] - col0),
            int((lo[1] - row0) * cols),
            int((hi[1] - row0 + 1) * cols),
        )
        odds = self._odds.reshape(-1)
        for index, delta in ((hits, self.hit), (misses, self.miss)):
            value = np.nan_to_num(odds[index], nan=0.0) + delta
            odds[index] = np.clip(value, self.lo_clamp, self.hi_clamp)

    def grid(self) -> GridMap:
        """The fused grid, cropped to the cells seen plus one cell all round."""
        seen = ~np.isnan(self._odds)
        if not seen.any():
            return GridMap(np.full((1, 1), UNKNOWN, dtype=np.int8), self.cell, (0.0, 0.0))
        rows, cols = np.flatnonzero(seen.any(axis=1)), np.flatnonzero(seen.any(axis=0))
        r0, r1 = rows[0] - 1, rows[-1] + 2
        c0, c1 = cols[0] - 1, cols[-1] + 2  # within the array: `_cover` keeps a cell to spare
        odds = self._odds[r0:r1, c0:c1]
        data = np.full(odds.shape, UNKNOWN, dtype=np.int8)
        data[seen[r0:r1, c0:c1]] = FREE
        data[odds > 0] = OCCUPIED  # NaN compares False: unseen stays unknown
        assert self._lo is not None  # cells seen: `_cover` or `reserve` placed the array
        origin = (float((self._lo[0] + c0) * self.cell), float((self._lo[1] + r0) * self.cell))
        return GridMap(data, self.cell, origin)


def _hits_and_misses(hit: np.ndarray, miss: np.ndarray, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Unique hit indices, and unique miss indices that are no hit, both ascending, of flat
    indices in [first, stop): by presence arrays over that range (the rows the cells span), or
    by sorting when the range is mostly empty."""
    if not box_is_dense(stop - first, len(hit) + len(miss)):
        hits = np.unique(hit)
        return hits, np.setdiff1d(np.unique(miss), hits, assume_unique=True)
    is_hit = np.zeros(stop - first, bool)
    is_hit[hit - first] = True
    is_miss = np.zeros(stop - first, bool)
    is_miss[miss - first] = True
    is_miss &= ~is_hit
    return np.flatnonzero(is_hit) + first, np.flatnonzero(is_miss) + first


def assemble(local_grids: list[LocalGrid], poses_xyyaw: np.ndarray, cell: float = 0.05) -> GridMap:
    """Fuse local grids placed at their planar world poses into one GridMap (see `GridVotes`)."""
    poses = np.asarray(poses_xyyaw, dtype=np.float64).reshape(-1, 3)
    if len(poses) != len(local_grids):
        raise InputError(f"assemble: {len(local_grids)} local grids but {len(poses)} poses")
    votes = GridVotes(cell)
    for grid, pose in zip(local_grids, poses):
        votes.add(grid, pose)
    return votes.grid()
