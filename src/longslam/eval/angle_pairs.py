"""RPE pose pairs a rotation angle apart, as evo's `filters.filter_pairs_by_angle` (`-u d` / `-u r`).

Consecutive pairs: from pose 0, the next pose at which the rotation accumulated step by step
since the last chosen pose reaches delta. All pairs: every (i, j > i) whose direct relative
rotation is within tol of delta.
"""

from __future__ import annotations

import numpy as np

from longslam.core.errors import InputError
from longslam.eval.pairs import consecutive_pairs
from longslam.eval.relations import rotation_angle_rad


def pairs_by_angle(
    rotations: np.ndarray, delta: float, tol: float = 0.0, degrees: bool = False, all_pairs: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of (N, 3, 3) rotations `delta` (radians, or degrees) apart."""
    bound = 180.0 if degrees else np.pi
    if not 0.0 <= delta <= bound:
        raise InputError(f"RPE delta angle must be within [0, {bound:g}] {'deg' if degrees else 'rad'}, got {delta}")
    if degrees:
        delta, tol = np.deg2rad(delta), np.deg2rad(tol)
    rotations = np.asarray(rotations, dtype=np.float64)
    if all_pairs:
        firsts, seconds = [], []
        for i in range(len(rotations) - 1):
            # One row of the O(N^2) search at a time: memory stays O(N).
            angle = rotation_angle_rad(np.swapaxes(rotations[i], 0, 1)[None] @ rotations[i + 1 :])
            js = np.flatnonzero((delta - tol <= angle) & (angle <= delta + tol)) + i + 1
            firsts.append(np.full(len(js), i))
            seconds.append(js)
        if not firsts:
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        return np.concatenate(firsts).astype(int), np.concatenate(seconds).astype(int)
    return consecutive_pairs(rotation_angle_rad(np.swapaxes(rotations[:-1], 1, 2) @ rotations[1:]), delta)
