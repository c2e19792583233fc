"""Free space seen by the submap method's camera: 2D rays over the floor, kept per submap, that
clear the cells of the 2D map the camera saw through.

Why: the TSDF's truncation band (0.8 m) is four times as thick as the building's walls (0.2 m).
A wall seen from the room behind it leaves the back of that room's band, negative distances,
reaching into the corridor in front; averaged with the corridor's own view of the wall (often at
a grazing angle, so few samples that far out), it can move the zero crossing into the corridor,
and the 2D slice draws a wall there. The TSDF does not carve free space beyond its
band, so nothing in it says that the corridor's camera saw through those cells. These rays do
(Voxblox carves such voxels inside its TSDF; longslam's TSDF feeds registration, which this
leaves as it is).

A frame's depth, every `grid_free_space_interval` of frame time, becomes a `LocalGrid` (the
keyframe method's obstacle and free cells, as RTAB-Map makes them) voted into its submap's grid
at the frame's pose in the submap; a finished submap keeps the cells its votes decided, and at
the end every submap's cells are voted into one world grid at the submap's final origin
(`fuse_free_space`), so the free space moves with the trajectory as the TSDF does. `carve`
applies it to the grid sliced from the TSDF.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from scipy import ndimage

from longslam.core.frame import Intrinsics
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.slam.occupancy import GridVotes, LocalGrid, local_grid


class SubmapFreeSpace:
    """One submap's 2D votes (obstacle and free cells of each frame) in the submap's frame."""

    def __init__(self, cell: float, range_max: float, min_height: float, max_height: float, stride: int):
        self.cell = float(cell)
        self.range_max = float(range_max)
        self.min_height = float(min_height)
        self.max_height = float(max_height)
        self.stride = int(stride)
        self._votes: GridVotes | None = GridVotes(self.cell)
        self.cells: LocalGrid | None = None  # the decided cells, once finished

    def add(
        self,
        depth: np.ndarray,
        intrinsics: Intrinsics,
        camera_in_base: np.ndarray,
        robot_in_submap: np.ndarray,
    ) -> None:
        """Vote one depth image taken with the robot at (x, y, yaw) `robot_in_submap`."""
        if self._votes is None:
            raise RuntimeError("a finished submap's free space takes no more frames")
        seen = local_grid(
            depth, intrinsics, camera_in_base, self.cell, self.range_max, self.min_height, self.max_height, self.stride
        )
        self._votes.add(seen, robot_in_submap)

    def finish(self) -> LocalGrid:
        """Keep only the cells the votes decided (occupied or free), as a `LocalGrid` in the
        submap's frame: a few bytes per cell instead of the votes' dense array."""
        if self.cells is None:
            assert self._votes is not None  # dropped only once the cells are decided
            self.cells = grid_cells(self._votes.grid())
            self._votes = None
        return self.cells

    @property
    def nbytes(self) -> int:
        if self.cells is not None:
            return self.cells.nbytes
        assert self._votes is not None  # dropped only once the cells are decided
        return self._votes.nbytes


def grid_cells(grid: GridMap) -> LocalGrid:
    """A grid whose origin lies on its cell lattice as a `LocalGrid`: occupied cells as
    obstacles, free cells as free, indexed floor((x, y) / cell) in the grid's frame."""
    lo = np.rint(np.asarray(grid.origin) / grid.resolution).astype(np.int64)

    def cells(value: int) -> np.ndarray:
        rows, cols = np.nonzero(grid.data == value)
        out = np.column_stack([cols + lo[0], rows + lo[1]])
        small = not len(out) or np.abs(out).max() < np.iinfo(np.int16).max
        return out.astype(np.int16 if small else np.int32)

    return LocalGrid(cells(OCCUPIED), cells(FREE), float(grid.resolution))


def fuse_free_space(parts: Iterable[tuple[LocalGrid, np.ndarray]], cell: float) -> GridMap:
    """One world grid from (submap cells, the submap's origin x, y, yaw) pairs: each submap
    votes once per cell (`GridVotes`), so a wall one submap saw outweighs one other submap's rays
    through it."""
    votes = GridVotes(cell)
    for cells, origin in parts:
        votes.add(cells, origin)
    return votes.grid()


def carve(grid: GridMap, free_space: GridMap, margin: int = 1) -> GridMap:
    """`grid` with the cells `free_space` holds free made free, except within `margin` cells of
    a cell it holds occupied: occupied cells the camera saw through (the wall drawn into the
    room), and unknown ones (the TSDF knows free space only within its band of a surface).

    The margin keeps the wall's own face: the TSDF's zero crossing and the depth returns can
    fall in neighbouring cells (both on 0.1 m cells, the rays' cells moved twice by a rotation,
    into the submap and into the world), and rays that graze a wall cross the cell in front of
    the one they end in. The result covers both grids; their origins must lie on one cell
    lattice (the submap method's both do: a cell index times the resolution)."""
    if not np.isclose(grid.resolution, free_space.resolution):
        raise ValueError(f"carve: grid resolution {grid.resolution} but free space {free_space.resolution}")
    res = grid.resolution
    clear = free_space.data == FREE
    if margin > 0:
        clear &= ~ndimage.binary_dilation(free_space.data == OCCUPIED, np.ones((3, 3), bool), iterations=margin)
    free_rc = np.argwhere(clear)
    if not len(free_rc):
        return grid
    corner = [np.rint(np.asarray(g.origin) / res).astype(np.int64) for g in (grid, free_space)]  # (col, row)
    lo = np.minimum(corner[0], corner[1])
    hi = np.maximum(corner[0] + grid.data.shape[::-1], corner[1] + free_space.data.shape[::-1])
    data = np.full((hi[1] - lo[1], hi[0] - lo[0]), UNKNOWN, np.int8)
    (c0, r0), (c1, r1) = corner[0] - lo, corner[1] - lo
    data[r0 : r0 + grid.data.shape[0], c0 : c0 + grid.data.shape[1]] = grid.data
    data[free_rc[:, 0] + r1, free_rc[:, 1] + c1] = FREE
    return GridMap(data, res, (float(lo[0] * res), float(lo[1] * res)))
