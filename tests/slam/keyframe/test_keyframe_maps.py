"""The keyframe method's final maps (slam/keyframe/maps.py): streamed, and as the batch filter made them."""

from __future__ import annotations

import tracemalloc

import numpy as np

from longslam.core.geometry import CameraMount, pose_from_xyyaw
from longslam.core.geometry.cells import average_3d
from longslam.slam.keyframe.maps import assemble_maps
from longslam.slam.occupancy import GridVotes, LocalGrid

MOUNT = CameraMount(camera_height=1.25, floor_z=-0.4)
CELL, VOXEL = 0.05, 0.05


def nodes(n: int, points_per_node: int) -> tuple[np.ndarray, dict[int, tuple[LocalGrid, np.ndarray]]]:
    """Nodes along a 60 m corridor there and back, each with float32 points (in its base frame)
    of the corridor's walls within 6 m, and a small local grid: like a route's nodes, many see
    the same wall voxels, so the cloud is far smaller than the nodes' points."""
    rng = np.random.default_rng(7)
    x = np.concatenate([np.linspace(0, 60, n // 2), np.linspace(60, 0, n - n // 2)])
    poses = np.column_stack([x, rng.normal(0, 0.2, n), rng.uniform(-np.pi, np.pi, n)])
    along, up = np.meshgrid(np.arange(0, 60, 0.05), np.arange(0, 2.8, 0.05), indexing="ij")
    walls = np.concatenate([np.column_stack([along.ravel(), np.full(along.size, side), up.ravel()]) for side in (-3.0, 3.0)])
    data = {}
    for i in range(n):
        seen = walls[np.abs(walls[:, 0] - poses[i, 0]) < 6.0]
        world = seen[rng.choice(len(seen), points_per_node)] + rng.normal(0, 0.01, (points_per_node, 3))
        base = pose_from_xyyaw(poses[i], MOUNT.floor_z)
        points = ((world - base[:3, 3]) @ base[:3, :3]).astype(np.float32)  # world -> base frame
        obstacles = rng.integers(-40, 40, (50, 2)).astype(np.int16)
        free = rng.integers(-20, 20, (80, 2)).astype(np.int16)
        data[i] = (LocalGrid(np.unique(obstacles, axis=0), np.unique(free, axis=0), CELL), points)
    return poses, data


def batch_maps(poses: np.ndarray, data: dict) -> tuple[np.ndarray, np.ndarray]:
    """The maps as assemble_maps made them before it streamed: every node's cloud, concatenated."""
    votes, clouds = GridVotes(CELL), []
    for i, (grid, points) in data.items():
        votes.add(grid, poses[i])
        base = pose_from_xyyaw(poses[i], MOUNT.floor_z)
        clouds.append((points @ base[:3, :3].T + base[:3, 3]).astype(np.float32))
    return votes.grid().data, average_3d(np.concatenate(clouds).astype(np.float64), VOXEL).astype(np.float32)


def test_streamed_maps_equal_the_batch_maps_to_the_bit(tmp_path):
    poses, data = nodes(80, 1500)
    grid, cloud = assemble_maps(list(data), lambda i: poses[i], data.__getitem__, MOUNT, CELL, VOXEL, scratch_dir=tmp_path,
                                grid_reach=2.0)
    grid_data, expected = batch_maps(poses, data)
    assert np.array_equal(grid.data, grid_data)
    assert cloud.dtype == np.float32 and cloud.tobytes() == expected.tobytes()
    assert not list(tmp_path.iterdir()), "assemble_maps left its scratch files"


def traced_peak(make) -> int:
    tracemalloc.start()
    try:
        make()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_the_maps_never_hold_every_node_at_once(tmp_path):
    # 600,000 points, 7.2 MB as float32: the batch filter held them at least four times over
    # (the transformed list, its concatenation, float64, the voxel indices); streamed, what is
    # held is the grid's votes, the cloud and one slab of points.
    poses, data = nodes(150, 4000)
    batch = traced_peak(lambda: batch_maps(poses, data))
    streamed = traced_peak(lambda: assemble_maps(list(data), lambda i: poses[i], data.__getitem__, MOUNT, CELL, VOXEL,
                                                 scratch_dir=tmp_path, grid_reach=2.0))
    assert streamed < 0.35 * batch, f"streamed peak {streamed / 1e6:.1f} MB, batch {batch / 1e6:.1f} MB"
