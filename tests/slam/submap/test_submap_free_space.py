"""The submap method's free space (slam/submap/free_space.py): 2D rays that clear the cells of
the TSDF's slice the camera saw through, except at the walls the rays ended on."""

from __future__ import annotations

import numpy as np
import pytest

from longslam.core.frame import Intrinsics
from longslam.core.geometry import CameraMount
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.slam.submap.free_space import SubmapFreeSpace, carve, fuse_free_space, grid_cells
from longslam.slam.submap.global_map import grid_from_tsdf
from longslam.slam.submap.tsdf import TSDF

RES = 0.1
INTRINSICS = Intrinsics.from_fov(64, 48, 90.0)
MOUNT = CameraMount(1.25)


def wall_depth(distance: float) -> np.ndarray:
    """Depth of a wall `distance` m ahead of a camera looking along it at the mount's height,
    the floor below the horizon where it is nearer than the wall."""
    rows = np.arange(INTRINSICS.height)[:, None] - INTRINSICS.cy
    floor = np.where(rows > 0, MOUNT.camera_height * INTRINSICS.fy / np.maximum(rows, 1e-9), np.inf)
    return np.broadcast_to(np.minimum(floor, distance), (INTRINSICS.height, INTRINSICS.width)).astype(np.float32)


def test_carve_clears_what_the_rays_crossed_but_not_next_to_where_they_ended():
    grid = GridMap(np.full((6, 8), UNKNOWN, np.int8), RES, (1.0, 2.0))  # cells x 1.0..1.8, y 2.0..2.6
    grid.data[:, 7] = OCCUPIED  # the wall, x 1.7..1.8
    grid.data[:, 4] = OCCUPIED  # a wall drawn 0.3 m in front of it
    grid.data[:, 6] = OCCUPIED  # the wall's own face, a cell in front
    rays = GridMap(np.full((6, 10), UNKNOWN, np.int8), RES, (0.8, 2.0))  # x 0.8..1.8: two cells more
    rays.data[:, :9] = FREE
    rays.data[:, 9] = OCCUPIED  # the rays ended on the wall
    out = carve(grid, rays)
    assert out.origin == pytest.approx((0.8, 2.0)) and out.data.shape == (6, 10)  # both grids covered
    column = lambda x: out.values_at(np.column_stack([np.full(6, x), 2.05 + RES * np.arange(6)]))  # noqa: E731
    assert np.all(column(1.75) == OCCUPIED)
    assert np.all(column(1.65) == OCCUPIED)  # within a cell of where the rays ended: kept
    assert np.all(column(1.45) == FREE)  # seen through
    assert np.all(column(0.85) == FREE)  # unknown to the TSDF, free to the rays
    assert np.all(carve(grid, rays, margin=0).values_at([[1.65, 2.05]]) == FREE)
    with pytest.raises(ValueError, match="resolution"):
        carve(grid, GridMap(rays.data, 0.05, rays.origin))


def test_grid_cells_index_the_cells_in_the_grids_frame():
    grid = GridMap(np.full((2, 3), UNKNOWN, np.int8), RES, (-0.3, 0.5))
    grid.data[1, 2] = OCCUPIED  # x -0.1..0, y 0.6..0.7: cell (-1, 6)
    grid.data[0, 0] = FREE  # x -0.3..-0.2, y 0.5..0.6: cell (-3, 5)
    cells = grid_cells(grid)
    assert cells.obstacles.tolist() == [[-1, 6]] and cells.free.tolist() == [[-3, 5]] and cells.cell == RES


def test_a_submaps_rays_move_with_its_origin_and_free_the_way_to_the_wall():
    space = SubmapFreeSpace(RES, 8.0, 0.2, 1.5, stride=1)
    for x in (0.0, 0.5, 1.0):  # driving towards a wall 4.05 m ahead of the first pose
        space.add(wall_depth(4.05 - x), INTRINSICS, MOUNT.camera_in_base, np.array([x, 0.0, 0.0]))
    assert space.nbytes > 0
    cells = space.finish()
    assert space.finish() is cells and space.nbytes == cells.nbytes
    with pytest.raises(RuntimeError):
        space.add(wall_depth(3.0), INTRINSICS, MOUNT.camera_in_base, np.zeros(3))
    # The submap's origin at (10, 5) facing +y: the wall is 4.05 m up, at y = 9.05.
    world = fuse_free_space([(cells, np.array([10.0, 5.0, np.pi / 2]))], RES)
    assert np.all(world.values_at([[10.05, y] for y in np.arange(5.35, 8.9, 0.1)]) == FREE)
    assert world.values_at([[10.05, 9.05]])[0] == OCCUPIED
    assert world.values_at([[10.05, 9.6]])[0] == UNKNOWN  # behind the wall


def thin_wall_tsdf() -> TSDF:
    """A 0.2 m wall, x 2.0..2.2, as the TSDF holds it once seen from both rooms (as on
    paper-300m): the far room's band reaches behind the wall into the near room, where it
    outweighs the near room's few samples of a wall seen at a grazing angle, so the voxels at
    x 1.5 and 1.7 read negative, a zero crossing 0.5 m in front of the wall."""
    tsdf = TSDF(0.2, 0.8)
    axes = [np.arange(0.0, 4.2, 0.2), np.arange(-1.0, 1.0, 0.2), np.arange(0.0, 2.0, 0.2)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + 0.1
    column = np.round(centres[:, 0] / 0.2 - 0.5).astype(int)  # voxel column: x = 0.2 column + 0.1
    sdf = np.where(column <= 9, np.clip(2.0 - centres[:, 0], -0.8, 0.8), np.clip(centres[:, 0] - 2.2, -0.8, 0.8))
    sdf[(column == 7) | (column == 8)] = -0.15  # x 1.5 and 1.7: the far room's band
    tsdf.merge(centres, sdf, np.ones(len(centres)))
    return tsdf


def test_the_rays_clear_a_thin_walls_back_side_band_in_front_of_it():
    tsdf = thin_wall_tsdf()
    surface, _ = tsdf.surface_points(with_normals=False)
    grid = grid_from_tsdf(tsdf, surface, floor_z=0.0, resolution=RES)
    occupied = grid.cell_to_world(np.argwhere(grid.data == OCCUPIED))
    assert np.any(occupied[:, 0] < 1.8)  # the TSDF draws a wall in the near room
    space = SubmapFreeSpace(RES, 8.0, 0.2, 1.5, stride=1)
    for y in np.arange(-0.6, 0.7, 0.3):  # the near room's camera looks at the wall, 2 m away
        space.add(wall_depth(2.0), INTRINSICS, MOUNT.camera_in_base, np.array([0.0, y, 0.0]))
    carved = carve(grid, fuse_free_space([(space.finish(), np.zeros(3))], RES))
    kept = carved.cell_to_world(np.argwhere(carved.data == OCCUPIED))
    inner = kept[np.abs(kept[:, 1]) < 0.5]
    # The wall (both faces, a cell either side), and nothing in the near room.
    assert len(inner) and np.all((inner[:, 0] > 2.0 - RES - 1e-9) & (inner[:, 0] < 2.2 + RES + 1e-9))
    assert np.any(np.abs(inner[:, 0] - 2.0) <= RES)  # the near face stays
    assert np.all(carved.values_at([[x, 0.05] for x in (0.55, 1.05, 1.45, 1.75)]) == FREE)


def test_a_negative_margin_is_an_input_error_naming_the_parameter():
    from longslam.core.errors import InputError
    from longslam.slam.submap.config import SubmapConfig

    with pytest.raises(InputError, match="grid_free_space_margin must be >= 0, got -1"):
        SubmapConfig(grid_free_space_margin=-1)
