"""The local map scans are registered against: the last few hundred scans near the robot.

Scans are stored in the world frame at the pose the front end gave them online. The search
structure (a KD-tree over cell-averaged points, with a line normal per point) is rebuilt only
every few inserted scans: the newest scan adds little that the previous ones did not already
show, and a rebuild is the costliest part of a frame.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from longslam.core.geometry.cells import average_2d
from longslam.core.parameter import check_declared, param


@dataclass(frozen=True)
class LocalMapConfig:
    max_scans: int = param(300, "scans kept (about 30 s of driving at 10 Hz)", at_least=1)
    radius: float = param(15.0, "scans whose robot position is farther than this are left out", above=0, unit="m")
    cell: float = param(0.05, "size of the cells the merged points are averaged in", above=0, unit="m")
    rebuild_every: int = param(5, "inserted scans between rebuilds of the KD-tree", at_least=1)
    normal_neighbours: int = param(6, "points a line is fitted to", at_least=2, why="a line needs two points")
    max_line_spread: float = param(0.25, "neighbours farther than this do not make a line", above=0, unit="m")
    max_line_ratio: float = param(
        0.15, "smallest / largest eigenvalue above this: a corner or clutter, not a line", at_least=0, at_most=1
    )

    def __post_init__(self) -> None:
        check_declared(self, "front end", "local_map.")


class LocalMap:
    def __init__(self, config: LocalMapConfig | None = None):
        self.config = config or LocalMapConfig()
        self._scans: deque[tuple[np.ndarray, np.ndarray]] = deque()  # (robot xy, world points)
        self._since_rebuild = 0
        self.points = np.zeros((0, 2))
        self.normals = np.zeros((0, 2))
        self.tree: cKDTree | None = None

    def __len__(self) -> int:
        return len(self.points)

    def insert(self, pose: np.ndarray, scan_xy: np.ndarray) -> None:
        """Add a base-frame scan taken at planar `pose` (x, y, yaw)."""
        c, s = np.cos(pose[2]), np.sin(pose[2])
        world = scan_xy @ np.array([[c, s], [-s, c]]) + pose[:2]
        self._scans.append((np.asarray(pose[:2], dtype=np.float64).copy(), world))
        while len(self._scans) > self.config.max_scans:
            self._scans.popleft()
        self._since_rebuild += 1
        if self.tree is None or self._since_rebuild >= self.config.rebuild_every:
            self.rebuild(pose[:2])

    def rebuild(self, centre: np.ndarray) -> None:
        cfg = self.config
        self._since_rebuild = 0
        # The scans' positions as one array: a test per scan in Python cost more than the rest of
        # gathering them.
        where = np.array([xy for xy, _ in self._scans]).reshape(-1, 2) - centre
        near = np.hypot(where[:, 0], where[:, 1]) <= cfg.radius
        parts = [w for (_, w), keep in zip(self._scans, near) if keep and len(w)]
        if not parts:
            self.points, self.normals, self.tree = np.zeros((0, 2)), np.zeros((0, 2)), None
            return
        pts = average_2d(np.vstack(parts), cfg.cell)
        k = min(cfg.normal_neighbours, len(pts))
        if k < 3:
            self.points, self.normals, self.tree = np.zeros((0, 2)), np.zeros((0, 2)), None
            return
        tree = cKDTree(pts)
        dist, idx = tree.query(pts, k=k)
        nb = pts[idx]  # (M, k, 2)
        centred = nb - nb.mean(axis=1, keepdims=True)
        sxx = np.einsum("mk,mk->m", centred[..., 0], centred[..., 0])
        syy = np.einsum("mk,mk->m", centred[..., 1], centred[..., 1])
        sxy = np.einsum("mk,mk->m", centred[..., 0], centred[..., 1])
        # Closed-form eigen decomposition of the 2x2 scatter: the normal is the minor axis.
        half_tr, det = 0.5 * (sxx + syy), sxx * syy - sxy * sxy
        disc = np.sqrt(np.maximum(half_tr * half_tr - det, 0.0))
        lam_big, lam_small = half_tr + disc, half_tr - disc
        angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # major axis direction
        normals = np.column_stack([-np.sin(angle), np.cos(angle)])
        line = (lam_small <= cfg.max_line_ratio * np.maximum(lam_big, 1e-12)) & (dist[:, -1] <= cfg.max_line_spread)
        self.points, self.normals = pts[line], normals[line]
        self.tree = cKDTree(self.points) if len(self.points) >= 3 else None
