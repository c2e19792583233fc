"""k-means on binary descriptors, as DBoW2 runs it for a vocabulary tree.

Descriptors are rows of bytes (ORB: 32 bytes, 256 bits) compared by Hamming distance; a cluster's
centre is the bitwise majority of its members. The seeding and the loop follow DBoW2's
`TemplatedVocabulary::HKmeansStep` and `initiateClustersKMpp`, so a tree built here is the tree
DBoW2 would build from the same draws:

- seeding: the first centre uniformly at random, each next one drawn with probability
  proportional to D(x), the distance to the nearest centre so far (DBoW2 uses D, not the D^2 of
  the k-means++ paper); seeding stops early when every descriptor sits on a centre;
- assignment: the nearest centre, the first one on a tie;
- centres: the bitwise majority, a bit set when at least half the members (rounded up) have it;
- repeated until no assignment changes (DBoW2 has no cap; `max_iterations` bounds the rare
  oscillating case).
"""

from __future__ import annotations

import numpy as np

# Rows compared at once: the XOR and count blocks of CHUNK x k stay a few MB.
CHUNK = 1 << 15

_POPCOUNT = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint8)
_HAS_BITWISE_COUNT = hasattr(np, "bitwise_count")  # numpy >= 2.0


def check_descriptors(descriptors: np.ndarray, what: str = "descriptors") -> np.ndarray:
    """Descriptors as a C-contiguous (n, bytes) uint8 array; bytes a multiple of 8."""
    array = np.asarray(descriptors)
    if array.ndim != 2 or array.dtype != np.uint8:
        raise ValueError(f"{what}: expected an (n, bytes) uint8 array, got {array.dtype} with shape {array.shape}")
    if array.shape[1] == 0 or array.shape[1] % 8:
        raise ValueError(f"{what}: descriptor length {array.shape[1]} bytes is not a positive multiple of 8")
    return np.ascontiguousarray(array)


def xor_popcount(a64: np.ndarray, b64: np.ndarray) -> np.ndarray:
    """Hamming distances of descriptors viewed as uint64 words, broadcast over all but the last
    axis: a64 (..., W) against b64 (..., W) gives (...) uint16."""
    shape = np.broadcast_shapes(a64.shape[:-1], b64.shape[:-1])
    total = np.zeros(shape, dtype=np.uint16)
    # Word by word: a sum over the short last axis is numpy's slow case.
    for w in range(a64.shape[-1]):
        x = a64[..., w] ^ b64[..., w]
        total += (
            np.bitwise_count(x)
            if _HAS_BITWISE_COUNT
            else _POPCOUNT[x.view(np.uint8)].reshape(*x.shape, 8).sum(axis=-1, dtype=np.uint16)
        )
    return total


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, m) Hamming distances between the rows of `a` (n, bytes) and of `b` (m, bytes)."""
    a64 = np.ascontiguousarray(a).view(np.uint64)
    b64 = np.ascontiguousarray(b).view(np.uint64)
    out = np.empty((len(a64), len(b64)), dtype=np.int32)
    for start in range(0, len(a64), CHUNK):
        block = a64[start : start + CHUNK]
        out[start : start + len(block)] = xor_popcount(block[:, None, :], b64[None, :, :])
    return out


def _nearest(descriptors: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Index of each descriptor's nearest centre (the first on a tie, as DBoW2's strict '<')."""
    out = np.empty(len(descriptors), dtype=np.int64)
    for start in range(0, len(descriptors), CHUNK):  # never the whole (n, k) distance matrix
        out[start : start + CHUNK] = np.argmin(hamming(descriptors[start : start + CHUNK], centres), axis=1)
    return out


def majority(descriptors: np.ndarray) -> np.ndarray:
    """The bitwise majority of the rows, DBoW2's FORB::meanValue: a bit is set when at least
    ceil(n / 2) rows have it."""
    n = len(descriptors)
    if n == 1:
        return descriptors[0].copy()
    counts = np.zeros(descriptors.shape[1] * 8, dtype=np.int64)
    for start in range(0, n, CHUNK):
        counts += np.unpackbits(descriptors[start : start + CHUNK], axis=1).sum(axis=0, dtype=np.int64)
    return np.packbits(counts >= (n + 1) // 2)


def seed_centres(descriptors: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """DBoW2's k-means++ seeding: up to k rows of `descriptors` as initial centres (fewer when
    the descriptors have fewer distinct values)."""
    n = len(descriptors)
    chosen = [int(rng.integers(n))]
    nearest = hamming(descriptors, descriptors[chosen[0]][None, :])[:, 0].astype(np.float64)
    while len(chosen) < k:
        total = nearest.sum()
        if total <= 0:
            break
        # The first index whose running sum reaches a uniform draw in (0, total]: DBoW2's walk.
        cut = total * (1.0 - rng.random())
        index = min(int(np.searchsorted(np.cumsum(nearest), cut, side="left")), n - 1)
        chosen.append(index)
        np.minimum(nearest, hamming(descriptors, descriptors[index][None, :])[:, 0], out=nearest)
    return descriptors[chosen].copy()


def kmeans(
    descriptors: np.ndarray,
    k: int,
    rng: np.random.Generator,
    max_iterations: int = 100,
) -> tuple[np.ndarray, np.ndarray]:
    """Cluster binary descriptors into at most k groups.

    Returns (centres (c, bytes) uint8, labels (n,) int) with c <= k and every centre holding at
    least one descriptor. With n <= k each descriptor is its own cluster, as in DBoW2.
    """
    descriptors = check_descriptors(descriptors)
    if k < 2:
        raise ValueError(f"k must be at least 2, got {k}")
    n = len(descriptors)
    if n == 0:
        raise ValueError("no descriptors to cluster")
    if n <= k:
        return descriptors.copy(), np.arange(n)
    centres = seed_centres(descriptors, k, rng)
    labels = _nearest(descriptors, centres)
    for _ in range(max_iterations):
        order = np.argsort(labels, kind="stable")
        ends = np.cumsum(np.bincount(labels, minlength=len(centres)))
        grouped = descriptors[order]
        for c, members in enumerate(np.split(grouped, ends[:-1])):
            if len(members):  # an emptied cluster keeps its centre; it is dropped below if it stays empty
                centres[c] = majority(members)
        new = _nearest(descriptors, centres)
        if np.array_equal(new, labels):
            break
        labels = new
    used = np.unique(labels)
    if len(used) < len(centres):
        remap = np.full(len(centres), -1)
        remap[used] = np.arange(len(used))
        centres, labels = centres[used], remap[labels]
    return centres, labels
