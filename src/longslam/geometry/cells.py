"""Grouping integer grid cells without sorting.

The scan and the local grids bundle points per floor cell (the TSDF does the same in 3D, with
`slam.submap.tsdf.group_cells`). Sorting a 64-bit key per point (`np.unique`) was the largest
single cost of each: the cells of one depth image lie in a
box of at most a few hundred thousand cells, so a presence array over the box finds the same
groups in linear time. The groups come out in the order the sort gave (the order of the key
`(i << 32) + (j & 0xFFFFFFFF)`: i ascending, then j >= 0 ascending, then j < 0 ascending), so
every sum over them is the same to the bit.
"""

from __future__ import annotations

import numpy as np

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
    rank = np.cumsum(present, dtype=np.int64) - 1
    return np.flatnonzero(present), rank[linear]


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
