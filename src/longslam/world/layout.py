"""A floor plan made of axis-aligned rectangles of free space, plus furniture boxes.

Free space is the union of `free` rectangles (rooms, corridors, door openings); everything
else up to the plan's bounds is solid wall. Furniture stands inside free space and is an
obstacle for navigation and for the occupancy grid, but not a wall.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap


@dataclass(frozen=True)
class Rect:
    xmin: float
    ymin: float
    xmax: float
    ymax: float
    kind: str = "room"  # room, corridor, hall, door, ... (textures and look-alike groups use it)
    name: str = ""

    @property
    def center(self) -> tuple[float, float]:
        return (self.xmin + self.xmax) / 2.0, (self.ymin + self.ymax) / 2.0

    @property
    def size(self) -> tuple[float, float]:
        return self.xmax - self.xmin, self.ymax - self.ymin


@dataclass(frozen=True)
class Box:
    """A piece of furniture: an axis-aligned box standing on the floor."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float
    height: float
    kind: str = "table"


@dataclass
class FloorPlan:
    name: str
    bounds: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax of the whole plan
    free: list[Rect]
    furniture: list[Box] = field(default_factory=list)
    wall_height: float = 3.0
    # Look-alike stretches, as real buildings have: walls inside the second zone of a pair carry
    # the same textures as the walls at the same offset inside the first zone.
    lookalike_pairs: list[tuple[Rect, Rect]] = field(default_factory=list)
    # Named spots on the floor (x, y) that routes are written in.
    places: dict[str, tuple[float, float]] = field(default_factory=dict)

    def rect(self, name: str) -> Rect:
        for r in self.free:
            if r.name == name:
                return r
        raise KeyError(name)

    def grid_shape(self, resolution: float) -> tuple[int, int]:
        xmin, ymin, xmax, ymax = self.bounds
        return int(round((ymax - ymin) / resolution)), int(round((xmax - xmin) / resolution))

    def _cells(self, xmin: float, ymin: float, xmax: float, ymax: float, resolution: float) -> tuple[slice, slice]:
        bx, by = self.bounds[0], self.bounds[1]
        c0, c1 = int(round((xmin - bx) / resolution)), int(round((xmax - bx) / resolution))
        r0, r1 = int(round((ymin - by) / resolution)), int(round((ymax - by) / resolution))
        return slice(r0, r1), slice(c0, c1)

    def free_mask(self, resolution: float) -> np.ndarray:
        """(rows, cols) bool: True where there is floor with no wall (furniture ignored)."""
        mask = np.zeros(self.grid_shape(resolution), dtype=bool)
        for r in self.free:
            mask[self._cells(r.xmin, r.ymin, r.xmax, r.ymax, resolution)] = True
        return mask

    def furniture_mask(self, resolution: float) -> np.ndarray:
        mask = np.zeros(self.grid_shape(resolution), dtype=bool)
        for b in self.furniture:
            mask[self._cells(b.xmin, b.ymin, b.xmax, b.ymax, resolution)] = True
        return mask

    def occupancy(self, resolution: float = 0.05, wall_depth: float = 0.3) -> GridMap:
        """Ground-truth occupancy: free floor 0; walls within `wall_depth` of free space and
        furniture 100; solid interior and the outside -1 (no sensor can see there)."""
        free = self.free_mask(resolution)
        furniture = self.furniture_mask(resolution) & free
        near_free = ndimage.distance_transform_edt(~free) * resolution <= wall_depth
        data = np.full(free.shape, UNKNOWN, dtype=np.int8)
        data[near_free & ~free] = OCCUPIED
        data[free] = FREE
        data[furniture] = OCCUPIED
        return GridMap(data, resolution, (self.bounds[0], self.bounds[1]))
