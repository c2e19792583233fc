"""The keyframe method's maps, assembled at the end from every node at its optimised pose."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from longslam.core.geometry import CameraMount, pose_from_xyyaw
from longslam.core.geometry.voxel_stream import VoxelStream
from longslam.core.gridmap import GridMap
from longslam.slam.occupancy import GridVotes, LocalGrid


def assemble_maps(
    node_ids: list[int],
    estimate: Callable[[int], np.ndarray],
    grid_and_points: Callable[[int], tuple[LocalGrid, np.ndarray]],
    mount: CameraMount,
    grid_cell: float,
    cloud_voxel: float,
    scratch_dir: str | Path | None = None,
    grid_reach: float | None = None,
) -> tuple[GridMap, np.ndarray]:
    """The 2D occupancy grid (local grids at their nodes' poses) and the voxel-filtered 3D cloud.

    Nodes are taken one at a time (from RAM or long-term memory), and neither the grid nor the
    cloud holds every node's data at once: the grid keeps its vote counts, the cloud streams
    through `VoxelStream` (scratch files under `scratch_dir`), which gives the batch filter's
    cloud to the bit. `grid_reach` (m), how far a local grid reaches from its node, sizes the
    grid's array once from the nodes' positions."""
    votes = GridVotes(grid_cell)
    if grid_reach is not None and node_ids:
        xy = np.array([estimate(node_id)[:2] for node_id in node_ids], dtype=np.float64)
        reach = grid_reach + 2 * grid_cell  # a cell's centre, rotated, lands a cell beyond
        votes.reserve(xy.min(axis=0) - reach, xy.max(axis=0) + reach)
    with VoxelStream(cloud_voxel, scratch_dir) as cloud:
        for node_id in node_ids:
            grid, points = grid_and_points(node_id)
            xyyaw = estimate(node_id)
            votes.add(grid, xyyaw)
            # Node points are in the robot base frame (z up from the floor), so they move with the
            # base's pose on the floor, not with the camera's.
            base = pose_from_xyyaw(xyyaw, mount.floor_z)
            cloud.add((points @ base[:3, :3].T + base[:3, 3]).astype(np.float32))
        fused = votes.grid()
        del votes  # the vote array goes before the cloud is filtered
        return fused, cloud.result()
