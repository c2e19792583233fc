"""A trajectory in a frame of its own, placed in longslam's world, and sparse poses made per-frame.

A SLAM system outside longslam (a program, a wrapped library) writes its poses in its own map
frame, usually the camera at its first tracked frame. `anchor` places that frame in the world by
one pose: the system's first pose goes to a given world pose (the first odometry pose, as every
longslam method starts), and every other pose keeps its place relative to it,
`T_world_first * inv(T_map_first) * T_map_i`, which is what any constant change of the system's
map frame (a rotated world, an origin elsewhere) leaves unchanged.
"""

from __future__ import annotations

import numpy as np

from longslam.core.geometry.se3 import invert


def anchor(poses: np.ndarray, world_first: np.ndarray, first: int = 0) -> np.ndarray:
    """(N, 4, 4) poses in a system's own frame -> the same poses in the world, pose `first` placed
    at `world_first` (4, 4)."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    if not len(poses):
        return poses.copy()
    offset = np.asarray(world_first, dtype=np.float64) @ invert(poses[first])
    return offset @ poses


def hold_last(count: int, frames: np.ndarray, poses: np.ndarray, before: np.ndarray) -> np.ndarray:
    """(count, 4, 4) poses, one per frame, from `poses` given at the sorted frame indices `frames`:
    a frame without a pose holds the last pose given before it, and `before` (4, 4) until the first."""
    frames = np.asarray(frames, dtype=np.int64).reshape(-1)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    out = np.repeat(np.asarray(before, dtype=np.float64)[None], count, axis=0)
    if not len(frames):
        return out
    # For each frame, the last given frame index at or before it (-1: none yet).
    last = np.searchsorted(frames, np.arange(count), side="right") - 1
    given = last >= 0
    out[given] = poses[last[given]]
    return out
