"""RPE pose pairs chosen by what accumulates between them (path, rotation), as evo chooses them."""

from __future__ import annotations

import numpy as np


def consecutive_pairs(steps: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j): from pose 0, the next pose at which the steps (path lengths or
    rotation angles between consecutive poses) summed since the last chosen pose reach delta.

    A plain loop on purpose: evo sums the steps one by one from zero after each chosen pose, and
    a constant-speed ground truth (steps of 0.1 m: ten of them sum to 0.9999999999999999) lands
    on delta exactly, where any other summation order would pick different poses."""
    ids = [0]
    accumulated = 0.0
    for index, step in enumerate(np.asarray(steps, dtype=np.float64).tolist(), start=1):
        accumulated += step
        if accumulated >= delta:
            ids.append(index)
            accumulated = 0.0
    chosen = np.asarray(ids)
    return chosen[:-1], chosen[1:]
