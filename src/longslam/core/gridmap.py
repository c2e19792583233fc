"""A 2D occupancy grid in the world's floor plane (ROS conventions: -1 unknown, 0 free, 100 occupied)."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

UNKNOWN, FREE, OCCUPIED = -1, 0, 100


@dataclass
class GridMap:
    data: np.ndarray  # (rows, cols) int8; row i covers y in [oy + i*res, oy + (i+1)*res)
    resolution: float  # metres per cell
    origin: tuple[float, float]  # world (x, y) of the corner of cell (0, 0)

    @property
    def shape(self) -> tuple[int, int]:
        return self.data.shape

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) in metres, for plotting."""
        ox, oy = self.origin
        rows, cols = self.data.shape
        return ox, ox + cols * self.resolution, oy, oy + rows * self.resolution

    def world_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) world x, y -> (N, 2) integer (row, col); may lie outside the grid."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        col = np.floor((xy[:, 0] - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((xy[:, 1] - self.origin[1]) / self.resolution).astype(np.int64)
        return np.column_stack([row, col])

    def cell_to_world(self, rc: np.ndarray) -> np.ndarray:
        """(N, 2) (row, col) -> (N, 2) world x, y of the cell centres."""
        rc = np.asarray(rc, dtype=np.float64).reshape(-1, 2)
        x = self.origin[0] + (rc[:, 1] + 0.5) * self.resolution
        y = self.origin[1] + (rc[:, 0] + 0.5) * self.resolution
        return np.column_stack([x, y])

    def occupied_points(self) -> np.ndarray:
        """(N, 2) world x, y of the centres of the occupied cells."""
        return self.cell_to_world(np.argwhere(self.data == OCCUPIED))

    def inside(self, rc: np.ndarray) -> np.ndarray:
        rc = np.asarray(rc).reshape(-1, 2)
        rows, cols = self.data.shape
        return (rc[:, 0] >= 0) & (rc[:, 0] < rows) & (rc[:, 1] >= 0) & (rc[:, 1] < cols)

    def values_at(self, xy: np.ndarray, outside: int = UNKNOWN) -> np.ndarray:
        rc = self.world_to_cell(xy)
        ok = self.inside(rc)
        out = np.full(len(rc), outside, dtype=np.int8)
        out[ok] = self.data[rc[ok, 0], rc[ok, 1]]
        return out

    def describe(self) -> str:
        return json.dumps({"shape": list(self.shape), "resolution": self.resolution, "origin": list(self.origin)})
