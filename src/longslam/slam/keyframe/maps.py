"""The keyframe method's maps, assembled at the end from every node at its optimised pose."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from longslam.geometry import CameraMount
from longslam.gridmap import GridMap
from longslam.slam.occupancy import LocalGrid, assemble


def assemble_maps(
    node_ids: list[int],
    estimate: Callable[[int], np.ndarray],
    grid_and_points: Callable[[int], tuple[LocalGrid, np.ndarray]],
    mount: CameraMount,
    grid_cell: float,
    cloud_voxel: float,
) -> tuple[GridMap, np.ndarray]:
    """The 2D occupancy grid (local grids at their nodes' poses) and the voxel-filtered 3D cloud."""
    grids, clouds, node_poses = [], [], []
    for node_id in node_ids:
        grid, points = grid_and_points(node_id)
        grids.append(grid)
        xyyaw = estimate(node_id)
        # Node points are in the robot base frame (z up from the floor), so they move with the
        # base's pose on the floor, not with the camera's.
        base = mount.base_pose(xyyaw)
        clouds.append(points @ base[:3, :3].T + base[:3, 3])
        node_poses.append(xyyaw)
    grid_map = assemble(grids, np.array(node_poses), grid_cell)
    cloud = voxel_filter(np.concatenate(clouds) if clouds else np.zeros((0, 3)), cloud_voxel)
    return grid_map, cloud


def voxel_filter(points: np.ndarray, voxel: float) -> np.ndarray:
    """One point (the centroid) per occupied voxel."""
    if not len(points):
        return np.zeros((0, 3), np.float32)
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse.ravel(), points)
    return (sums / counts[:, None]).astype(np.float32)
