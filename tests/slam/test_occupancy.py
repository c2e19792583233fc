"""Occupancy from depth: obstacles in the 0.2-1.5 m band, free space by ray tracing, assembly."""

from __future__ import annotations

import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.geometry import base_to_camera
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN
from longslam.slam.occupancy import GridVotes, LocalGrid, assemble, local_grid

CAMERA_HEIGHT = 1.25
INTR = Intrinsics.from_fov(64, 48, 90)
CAM_IN_BASE = base_to_camera(CAMERA_HEIGHT)


def floor_depth(intr: Intrinsics = INTR) -> np.ndarray:
    """Depth of the floor plane seen by a level camera CAMERA_HEIGHT above it (0 above the horizon)."""
    v = np.arange(intr.height, dtype=np.float64)[:, None] + np.zeros((1, intr.width))
    down = (v - intr.cy) / intr.fy  # camera-frame y per metre of depth; y points down
    with np.errstate(divide="ignore"):
        depth = np.where(down > 0, CAMERA_HEIGHT / np.where(down > 0, down, 1.0), 0.0)
    return depth.astype(np.float32)


def wall_depth(distance: float, intr: Intrinsics = INTR) -> np.ndarray:
    """A wall facing the camera at `distance` (camera z = distance), floor where it is nearer."""
    floor = floor_depth(intr)
    depth = np.full(floor.shape, distance, dtype=np.float32)
    nearer_floor = (floor > 0) & (floor < distance)
    depth[nearer_floor] = floor[nearer_floor]
    return depth


def test_wall_gives_obstacles_at_its_distance_and_free_space_before_it():
    grid = local_grid(wall_depth(2.0), INTR, CAM_IN_BASE)
    assert len(grid.obstacles) > 0 and len(grid.free) > 0
    obs = grid.obstacle_points()
    assert np.all(np.abs(obs[:, 0] - 2.0) <= 0.05 + 1e-9)
    # The wall spans the 90 degree view: y from about -2 to 2 m.
    assert obs[:, 1].min() < -1.5 and obs[:, 1].max() > 1.5
    free = grid.free_points()
    assert free[:, 0].max() < 2.0
    assert free[:, 0].min() < 0.5  # cleared from the robot outwards
    # The corridor straight ahead is free all the way to the wall.
    ahead = grid.free[grid.free[:, 1] == 0, 0]
    assert set(range(0, 39)) <= set(ahead.tolist())
    assert grid.obstacles.dtype == np.int16 and grid.free.dtype == np.int16
    # Obstacle and free cells never overlap.
    both = {tuple(c) for c in grid.obstacles.tolist()} & {tuple(c) for c in grid.free.tolist()}
    assert not both


def test_floor_only_gives_no_obstacles():
    grid = local_grid(floor_depth(), INTR, CAM_IN_BASE, range_max=5.0)
    assert len(grid.obstacles) == 0
    assert len(grid.free) > 0
    # Floor seen beyond range_max still clears space, but only up to range_max.
    assert np.linalg.norm(grid.free_points(), axis=1).max() <= 5.0 + 0.05 * np.sqrt(2)


def test_points_outside_height_band_are_not_obstacles():
    # A wall 2 m ahead seen only through a narrow band of rows near the top of the image
    # (above 1.5 m) must not produce obstacles.
    depth = wall_depth(2.0)
    heights = CAMERA_HEIGHT - (np.arange(INTR.height) - INTR.cy) / INTR.fy * 2.0
    depth[heights <= 1.5, :] = 0.0
    grid = local_grid(depth, INTR, CAM_IN_BASE, stride=1)
    assert len(grid.obstacles) == 0


def test_empty_depth_gives_empty_grid():
    grid = local_grid(np.zeros((INTR.height, INTR.width), np.float32), INTR, CAM_IN_BASE)
    assert grid.obstacles.shape == (0, 2) and grid.free.shape == (0, 2)
    assert grid.nbytes == 0
    gmap = assemble([grid], [(0.0, 0.0, 0.0)])
    assert np.all(gmap.data == UNKNOWN)
    assert np.all(assemble([], np.zeros((0, 3))).data == UNKNOWN)


def test_assemble_places_wall_in_world():
    # The same wall, world x = 2, seen from three places: 2 m before it, 1 m before it, and
    # from the far side (robot at x = 4 facing back along -x).
    views = [((0.0, 0.0, 0.0), 2.0), ((1.0, 0.0, 0.0), 1.0), ((4.0, 0.3, np.pi), 2.0)]
    # stride 1: the test image is tiny, and rays to every other column would leave gaps.
    grids = [local_grid(wall_depth(d), INTR, CAM_IN_BASE, stride=1) for _, d in views]
    gmap = assemble(grids, np.array([p for p, _ in views]))
    assert gmap.resolution == 0.05

    rows, cols = np.nonzero(gmap.data == OCCUPIED)
    occ = gmap.cell_to_world(np.column_stack([rows, cols]))
    assert len(occ) > 20 and np.ptp(occ[:, 1]) > 3.0
    assert np.all(np.abs(occ[:, 0] - 2.0) <= 0.1)

    # Free space in front of and behind the wall, unknown far off to the side.
    assert np.all(gmap.values_at([[0.52, 0.02], [1.52, 0.02], [3.02, 0.32]]) == FREE)
    assert gmap.values_at([[0.52, 4.02]])[0] == UNKNOWN
    assert gmap.values_at([[2.02, 0.0]])[0] == OCCUPIED


def test_assemble_weighs_hits_and_misses_as_log_odds():
    # RTAB-Map's log-odds: a hit (p 0.7) outweighs one miss (p 0.4) but not three, so a wall
    # survives a grazing ray from another node, and a one-off obstacle is cleared by the views
    # that saw through it.
    blip = LocalGrid(np.array([[10, 0]], np.int16), np.zeros((0, 2), np.int16), 0.05)
    clear = LocalGrid(np.zeros((0, 2), np.int16), np.array([[10, 0], [11, 0]], np.int16), 0.05)
    cell = [[0.525, 0.025]]
    assert assemble([blip, clear], np.zeros((2, 3))).values_at(cell)[0] == OCCUPIED
    assert assemble([blip, clear, clear, clear], np.zeros((4, 3))).values_at(cell)[0] == FREE
    # Clamping: a wall seen a hundred times is not frozen; enough later misses clear it.
    many = assemble([blip] * 100 + [clear] * 9, np.zeros((109, 3)))
    assert many.values_at(cell)[0] == FREE
    assert assemble([blip] * 100 + [clear] * 8, np.zeros((108, 3))).values_at(cell)[0] == OCCUPIED


def test_bad_input_is_named():
    with pytest.raises(InputError, match="does not match"):
        local_grid(np.zeros((10, 10), np.float32), INTR, CAM_IN_BASE)
    with pytest.raises(InputError, match="local grids"):
        assemble([], np.zeros((1, 3)))


def test_a_grid_reaching_the_edge_of_the_vote_array_is_kept_whole():
    # The second grid fits inside the array the first one made, up to its last row: the fused
    # grid once came out empty (a slice from row -1) on a 1 km route.
    votes = GridVotes(0.05)
    first = LocalGrid(np.array([[0, 0]], np.int16), np.array([[1, 0]], np.int16), 0.05)
    votes.add(first, np.zeros(3))
    edge = -votes.GROW_CELLS  # the array's first row and column, in this frame's cells
    second = LocalGrid(np.array([[edge, edge]], np.int16), np.zeros((0, 2), np.int16), 0.05)
    votes.add(second, np.zeros(3))
    gmap = votes.grid()
    # rows -256..0, columns -256..1, and one unknown cell all round
    assert gmap.data.shape == (-edge + 1 + 2, -edge + 2 + 2)
    corner = edge * 0.05 + 0.025
    assert (gmap.values_at(np.array([[0.025, 0.025], [corner, corner]])) == OCCUPIED).all()
    assert gmap.values_at(np.array([[0.075, 0.025]]))[0] == FREE
    assert (gmap.data[0] == UNKNOWN).all() and (gmap.data[:, 0] == UNKNOWN).all()


def test_a_reserved_vote_array_gives_the_same_grid_and_grows_if_it_must():
    rng = np.random.default_rng(3)
    grids = [LocalGrid(np.unique(rng.integers(-30, 30, (40, 2)), axis=0).astype(np.int16),
                       np.unique(rng.integers(-15, 15, (60, 2)), axis=0).astype(np.int16), 0.05) for _ in range(20)]
    poses = np.column_stack([np.linspace(0, 12, 20), np.linspace(-2, 3, 20), rng.uniform(-np.pi, np.pi, 20)])
    grown = GridVotes(0.05)
    for grid, pose in zip(grids, poses):
        grown.add(grid, pose)
    # Reserved to fit every grid, and reserved too small (the last grids reach beyond it).
    for lo, hi in (([-3.0, -5.0], [15.0, 6.0]), ([0.0, 0.0], [5.0, 1.0])):
        reserved = GridVotes(0.05)
        reserved.reserve(np.array(lo), np.array(hi))
        for grid, pose in zip(grids, poses):
            reserved.add(grid, pose)
        a, b = grown.grid(), reserved.grid()
        assert np.array_equal(a.data, b.data) and a.origin == b.origin
    with pytest.raises(RuntimeError, match="before the first add"):
        reserved.reserve(np.zeros(2), np.ones(2))


@pytest.mark.parametrize("spread", [5, 100_000])  # a dense box (presence arrays) and a sparse one (sorting)
def test_cells_are_removed_and_votes_made_unique_as_sorting_does(spread):
    from longslam.slam.occupancy import _hits_and_misses, _remove_cells

    rng = np.random.default_rng(2)
    cells = rng.integers(-spread, spread, (400, 2))
    drop = np.vstack([cells[::3], rng.integers(-spread, spread, (50, 2))])
    key = lambda c: (c[:, 0].astype(np.int64) << 32) + (c[:, 1].astype(np.int64) & 0xFFFFFFFF)  # noqa: E731
    np.testing.assert_array_equal(_remove_cells(cells, drop), cells[~np.isin(key(cells), key(drop))])

    first = 7
    hit = rng.integers(first, first + 40 * spread, 300)
    miss = np.concatenate([hit[::2], rng.integers(first, first + 40 * spread, 300)])
    hits, misses = _hits_and_misses(hit, miss, first, first + 40 * spread)
    np.testing.assert_array_equal(hits, np.unique(hit))
    np.testing.assert_array_equal(misses, np.setdiff1d(np.unique(miss), np.unique(hit)))
