"""The keyframe method's maps, assembled at the end from every node at its optimised pose."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from longslam.geometry import CameraMount, pose_from_xyyaw
from longslam.geometry.cells import average_3d
from longslam.gridmap import GridMap
from longslam.slam.keyframe.occupancy import GridVotes, LocalGrid


def assemble_maps(
    node_ids: list[int],
    estimate: Callable[[int], np.ndarray],
    grid_and_points: Callable[[int], tuple[LocalGrid, np.ndarray]],
    mount: CameraMount,
    grid_cell: float,
    cloud_voxel: float,
) -> tuple[GridMap, np.ndarray]:
    """The 2D occupancy grid (local grids at their nodes' poses) and the voxel-filtered 3D cloud.

    Nodes are taken one at a time (from RAM or long-term memory), so only the grid's vote counts
    and the cloud's points are held, never every node's local grid at once."""
    votes = GridVotes(grid_cell)
    clouds = []
    for node_id in node_ids:
        grid, points = grid_and_points(node_id)
        xyyaw = estimate(node_id)
        votes.add(grid, xyyaw)
        # Node points are in the robot base frame (z up from the floor), so they move with the
        # base's pose on the floor, not with the camera's.
        base = pose_from_xyyaw(xyyaw, mount.floor_z)
        clouds.append((points @ base[:3, :3].T + base[:3, 3]).astype(np.float32))
    cloud = voxel_filter(np.concatenate(clouds).astype(np.float64) if clouds else np.zeros((0, 3)), cloud_voxel)
    return votes.grid(), cloud


def voxel_filter(points: np.ndarray, voxel: float) -> np.ndarray:
    """One point (the centroid) per occupied voxel, float32."""
    return average_3d(points, voxel).astype(np.float32)
