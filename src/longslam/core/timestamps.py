"""Matching timestamps, the three ways longslam needs it; each in one place.

- `match_every`: every frame to its nearest pose (a sequence's odometry: each frame needs one);
- `one_to_one_nearest`: evo's nearest-stamp pairing, made one-to-one (scoring trajectories);
- `associate_lists`: TUM's associate.py, greedy closest-first (pairing rgb.txt with depth.txt).
"""

from __future__ import annotations

import numpy as np

from longslam.core.errors import InputError


def nearest_indices(query: np.ndarray, stamps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each query stamp, the index of the nearest of the sorted `stamps` (the earlier one on a
    tie, as evo does) and the time between them. `stamps` must not be empty."""
    query = np.asarray(query, dtype=np.float64)
    stamps = np.asarray(stamps, dtype=np.float64)
    above = np.searchsorted(stamps, query, side="right")
    upper = np.minimum(above, len(stamps) - 1)
    lower = np.maximum(above - 1, 0)
    diff_upper = np.abs(stamps[upper] - query)
    diff_lower = np.where(above > 0, np.abs(query - stamps[lower]), np.inf)
    take_upper = diff_upper < diff_lower
    return np.where(take_upper, upper, lower), np.where(take_upper, diff_upper, diff_lower)


def match_every(query: np.ndarray, stamps: np.ndarray, max_diff: float, source: str) -> np.ndarray:
    """For each query stamp, the index of the nearest stamp; InputError (naming `source`, the first
    frame without one and the nearest pose) if any is farther than `max_diff`."""
    query = np.asarray(query, dtype=np.float64)
    stamps = np.asarray(stamps, dtype=np.float64)
    if len(stamps) == 0:
        if len(query):
            raise InputError(f"{source} holds no poses, so frame t={query[0]:.6f} has no odometry")
        return np.zeros(0, dtype=np.int64)
    nearest, diff = nearest_indices(query, stamps)
    bad = np.flatnonzero(diff > max_diff)
    if len(bad):
        first = bad[0]
        more = f" (and {len(bad) - 1} more frames)" if len(bad) > 1 else ""
        raise InputError(
            f"{source}: no pose within {max_diff} s of frame t={query[first]:.6f}{more}; "
            f"nearest pose is at t={stamps[nearest[first]]:.6f}"
        )
    return nearest


def one_to_one_nearest(
    short_stamps: np.ndarray, long_stamps: np.ndarray, max_diff: float
) -> tuple[np.ndarray, np.ndarray]:
    """Indices (into short, into long) of one-to-one nearest-stamp matches within max_diff.

    Both stamp arrays must be sorted. Each short stamp takes its nearest long stamp (the earlier
    one on a tie, as evo does); when several short stamps take the same long stamp only the
    closest keeps it (the earliest on a tie), so the result is one-to-one and stays sorted.
    """
    short_stamps = np.asarray(short_stamps, dtype=np.float64)
    long_stamps = np.asarray(long_stamps, dtype=np.float64)
    if not len(short_stamps) or not len(long_stamps):
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    nearest, diff = nearest_indices(short_stamps, long_stamps)
    short_idx = np.flatnonzero(diff <= max_diff)
    if not len(short_idx):
        return short_idx, short_idx.copy()
    long_idx, diff = nearest[short_idx], diff[short_idx]
    # Sorted by long index, then by time difference: the first of each run is the one to keep.
    order = np.lexsort((diff, long_idx))
    first = np.r_[True, long_idx[order][1:] != long_idx[order][:-1]]
    keep = np.sort(order[first])
    return short_idx[keep], long_idx[keep]


def associate_lists(first: np.ndarray, second: np.ndarray, max_diff: float) -> list[tuple[int, int]]:
    """One-to-one association of two timestamp lists, as TUM's associate.py does.

    Every pair closer than `max_diff` is a candidate; candidates are taken greedily, closest first,
    each stamp used at most once. Returns (index in first, index in second) pairs sorted by the
    first stamp.
    """
    return [(int(i), int(j)) for i, j in associate_indices(first, second, max_diff)]


def associate_indices(first: np.ndarray, second: np.ndarray, max_diff: float) -> np.ndarray:
    """`associate_lists` as a (K, 2) int64 array, with no Python object per candidate: a long
    route's index files pair 20,000 stamps and more."""
    first = np.asarray(first, dtype=np.float64).reshape(-1)
    second = np.asarray(second, dtype=np.float64).reshape(-1)
    order = np.argsort(second, kind="stable")
    sorted_second = second[order]
    lo = np.searchsorted(sorted_second, first - max_diff, side="left")
    hi = np.searchsorted(sorted_second, first + max_diff, side="right")
    counts = np.maximum(hi - lo, 0)
    i = np.repeat(np.arange(len(first)), counts)
    k = lo[i] + (np.arange(len(i)) - np.repeat(np.cumsum(counts) - counts, counts))
    j = order[k]
    d = np.abs(first[i] - second[j])
    keep = d <= max_diff
    i, j, d = i[keep], j[keep], d[keep]
    by_closeness = np.lexsort((j, i, d))  # closest first; ties by first index, then second
    i, j = i[by_closeness], j[by_closeness]
    if len(np.unique(i)) < len(i) or len(np.unique(j)) < len(j):
        # Some stamp has two candidates: take them greedily (rare; most lists pair one to one).
        used_first = np.zeros(len(first), bool)
        used_second = np.zeros(len(second), bool)
        take = np.zeros(len(i), bool)
        for n, (a, b) in enumerate(zip(i.tolist(), j.tolist())):
            if not used_first[a] and not used_second[b]:
                used_first[a] = used_second[b] = take[n] = True
        i, j = i[take], j[take]
    by_first = np.lexsort((i, first[i]))
    return np.stack([i[by_first], j[by_first]], axis=1).astype(np.int64).reshape(-1, 2)
