"""The submap method's 2D slice and mesh from a fused TSDF: no stripes, whole walls, no sheets
in a wall's shadow."""

from __future__ import annotations

import numpy as np

from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN
from longslam.slam.submap.global_map import grid_from_tsdf, mesh_arrays
from longslam.slam.submap.tsdf import TSDF

VOXEL, TRUNCATION = 0.2, 0.8


def wall_tsdf(behind: float = 2.8) -> TSDF:
    """A wall x = 2 m seen from x < 2: signed distances of the voxels from x = 0 to `behind`,
    y -2..2 m, z 0..2 m, clamped to the truncation."""
    tsdf = TSDF(VOXEL, TRUNCATION)
    axes = [np.arange(0.0, behind, VOXEL), np.arange(-2.0, 2.0, VOXEL), np.arange(0.0, 2.0, VOXEL)]
    ijk = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + VOXEL / 2
    sdf = np.clip(2.0 - ijk[:, 0], -TRUNCATION, TRUNCATION)
    tsdf.merge(ijk, sdf, np.ones(len(ijk)))
    return tsdf


def test_the_slice_has_no_stripes_and_a_whole_wall_at_a_grid_finer_than_the_voxels():
    tsdf = wall_tsdf()
    surface, _ = tsdf.surface_points(with_normals=False)
    grid = grid_from_tsdf(tsdf, surface, floor_z=0.0, resolution=0.1)
    # Every cell between the robot's side and the wall, away from the block's edges, is free.
    xs, ys = np.meshgrid(np.arange(0.25, 1.8, 0.1), np.arange(-1.75, 1.8, 0.1))
    values = grid.values_at(np.column_stack([xs.ravel(), ys.ravel()]))
    assert np.all(values == FREE)
    # The wall: an occupied cell within a cell of x = 2 m in every 0.1 m row, and nowhere else.
    occupied = grid.cell_to_world(np.argwhere(grid.data == OCCUPIED))
    assert np.all(np.abs(occupied[:, 0] - 2.0) <= 0.1 + 1e-9)
    rows = np.unique(np.floor(occupied[:, 1] / 0.1).astype(int))
    assert set(range(-19, 19)) <= set(rows.tolist())
    # Behind the wall is not free.
    assert np.all(grid.values_at([[2.45, 0.05], [2.65, -1.05]]) != FREE)
    assert grid.values_at([[5.0, 0.0]])[0] == UNKNOWN


def test_the_mesh_has_no_sheet_where_a_clamped_far_side_meets_a_grazing_ray():
    tsdf = wall_tsdf()
    # A ray that grazed past the wall saw the layer behind its clamped far side as free.
    layer = np.stack(np.meshgrid([2.9], np.arange(-1.9, 2.0, VOXEL), np.arange(0.1, 2.0, VOXEL), indexing="ij"), -1).reshape(-1, 3)
    tsdf.merge(layer, np.full(len(layer), TRUNCATION), np.ones(len(layer)))
    vertices, triangles = mesh_arrays(tsdf)
    assert np.sum(np.abs(vertices[:, 0] - 2.0) < 0.05) > 100  # the wall is meshed
    assert not np.any(vertices[:, 0] > 2.5)  # and nothing between the far side and that layer
