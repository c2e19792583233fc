"""Grouping points by grid cell, in 2D (floor cells) and 3D (voxels), and averaging per cell.

The front end's scan and local map, the keyframe method's local grids and cloud, and the submap
method's TSDF all bundle points per cell. Sorting a 64-bit key per point (`np.unique`) was the
largest single cost of each: the cells of one depth image lie in a box of at most a few hundred
thousand cells, so a presence array over the box finds the same groups in linear time, and the
sort stays for a sparse box. The groups come out in the order the sort gave, so every sum over
them is the same to the bit:
- 2D: the key `(i << 32) + (j & 0xFFFFFFFF)`: i ascending, then j >= 0 ascending, then j < 0;
- 3D: the packed key of `pack_3d` (21 bits an axis): i, then j, then k ascending.
"""

from __future__ import annotations

import numpy as np

_BITS = 21  # per axis in a packed 3D index
_OFFSET = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1

# Above this many cells per point, the box is mostly empty and the sort is cheaper.
_MAX_CELLS_PER_POINT = 8
_MIN_BOX = 1 << 20


def box_is_dense(cells: int, points: int) -> bool:
    """Whether a presence array over a box of `cells` cells beats sorting `points` keys."""
    return cells <= _MAX_CELLS_PER_POINT * points + _MIN_BOX


def box_groups(linear: np.ndarray, cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Groups of (N,) row-major indices into a box of `cells` cells: (the occupied indices,
    ascending; each point's group), as `np.unique(linear, return_inverse=True)` gives them."""
    present = np.zeros(cells, bool)
    present[linear] = True
    occupied = np.flatnonzero(present)
    # Each occupied cell's rank written at its index: the box is read once as bytes, where a
    # cumulative sum wrote eight bytes per cell of the box. Only occupied cells are read back.
    rank = np.empty(cells, np.int64)
    rank[occupied] = np.arange(len(occupied), dtype=np.int64)
    return occupied, rank[linear]


def group_cells_2d(i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique cells of (N,) integer indices i, j: (unique i, unique j, inverse (N,)), in the order
    of `np.unique((i << 32) + (j & 0xFFFFFFFF), return_inverse=True)`."""
    i = np.asarray(i, dtype=np.int64).reshape(-1)
    j = np.asarray(j, dtype=np.int64).reshape(-1)
    if not len(i):
        empty = np.zeros(0, np.int64)
        return empty, empty, empty
    i_low, j_low, j_high = int(i.min()), int(j.min()), int(j.max())
    # j as the key's unsigned low half orders: 0, 1, ..., j_high, then j_low, ..., -1.
    negative_base = max(j_high, -1) + 1
    j_rank = np.where(j >= 0, j, j - j_low + negative_base) if j_low < 0 else j
    j_span = (negative_base - j_low) if j_low < 0 else j_high + 1
    cells = (int(i.max()) - i_low + 1) * j_span
    if not box_is_dense(cells, len(i)):
        keys, inverse = np.unique((i << 32) + (j & 0xFFFFFFFF), return_inverse=True)
        return keys >> 32, (keys & 0xFFFFFFFF).astype(np.uint32).astype(np.int32).astype(np.int64), inverse.reshape(-1)
    occupied, inverse = box_groups((i - i_low) * j_span + j_rank, cells)
    ui, uj_rank = np.divmod(occupied, j_span)
    uj = np.where(uj_rank < negative_base, uj_rank, uj_rank - negative_base + j_low) if j_low < 0 else uj_rank
    return ui + i_low, uj, inverse


def pack_3d(ijk: np.ndarray) -> np.ndarray:
    """(N, 3) integer indices -> (N,) int64 keys (each axis within +-2^20), ordered as (i, j, k)."""
    ijk = np.asarray(ijk, dtype=np.int64)
    return _pack_axes(ijk[:, 0], ijk[:, 1], ijk[:, 2])


def _pack_axes(i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
    # Axis by axis: no (N, 3) copy of a large cloud's indices.
    return ((i + _OFFSET) << (2 * _BITS)) | ((j + _OFFSET) << _BITS) | (k + _OFFSET)


def unpack_3d(keys: np.ndarray) -> np.ndarray:
    """(N,) keys of `pack_3d` -> (N, 3) integer indices."""
    keys = np.asarray(keys, dtype=np.int64)
    return np.column_stack([(keys >> (2 * _BITS)) & _MASK, (keys >> _BITS) & _MASK, keys & _MASK]) - _OFFSET


def group_cells_3d(
    i: np.ndarray, j: np.ndarray, k: np.ndarray
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """Unique cells of integer indices given per axis ((N,) each): ((i, j, k) of the unique
    cells, ordered as their packed keys; inverse (N,)), as
    `np.unique(pack_3d(ijk), return_inverse=True)` gives them."""
    if not len(i):
        empty = np.zeros(0, np.int64)
        return (empty, empty, empty), empty
    low = (int(i.min()), int(j.min()), int(k.min()))
    span = (int(i.max()) - low[0] + 1, int(j.max()) - low[1] + 1, int(k.max()) - low[2] + 1)
    cells = span[0] * span[1] * span[2]
    if not box_is_dense(cells, len(i)):
        keys, inverse = np.unique(
            _pack_axes(np.asarray(i, np.int64), np.asarray(j, np.int64), np.asarray(k, np.int64)), return_inverse=True
        )
        ijk = unpack_3d(keys)
        return (ijk[:, 0], ijk[:, 1], ijk[:, 2]), inverse.reshape(-1)
    # Row-major over (i, j, k) is the packed keys' order.
    occupied, inverse = box_groups(((i - low[0]) * span[1] + (j - low[1])) * span[2] + (k - low[2]), cells)
    ui, rest = np.divmod(occupied, span[1] * span[2])
    uj, uk = np.divmod(rest, span[2])
    return (ui + low[0], uj + low[1], uk + low[2]), inverse


def cell_means(points: np.ndarray, inverse: np.ndarray, groups: int) -> np.ndarray:
    """(groups, D) mean of the (N, D) points of each group, summed in point order."""
    counts = np.bincount(inverse, minlength=groups)
    sums = [np.bincount(inverse, weights=points[:, a], minlength=len(counts)) for a in range(points.shape[1])]
    return np.column_stack(sums) / counts[:, None]


def average_2d(xy: np.ndarray, cell: float) -> np.ndarray:
    """Mean of the (N, 2) points in each `cell`-sized square: (M, 2), M <= N."""
    if not len(xy):
        return np.zeros((0, 2))
    i, j, inverse = group_cells_2d(
        np.floor(xy[:, 0] / cell).astype(np.int64), np.floor(xy[:, 1] / cell).astype(np.int64)
    )
    return cell_means(xy, inverse, len(i))


def average_3d(points: np.ndarray, voxel: float) -> np.ndarray:
    """Mean of the (N, 3) points in each `voxel`-sized cube: (M, 3) float64, M <= N."""
    if not len(points):
        return np.zeros((0, 3))
    points = np.asarray(points, dtype=np.float64)
    (i, _, _), inverse = group_cells_3d(*(np.floor(points[:, a] / voxel).astype(np.int64) for a in range(3)))
    return cell_means(points, inverse, len(i))
