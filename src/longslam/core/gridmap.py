"""A 2D occupancy grid in the world's floor plane (ROS conventions: -1 unknown, 0 free, 100 occupied)."""

from __future__ import annotations

import zipfile

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.io.atomic import atomic_path, naming_the_file

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

    def save(self, path: str | Path) -> None:
        """Write as .npz (data, resolution, origin), via a temporary name."""
        path = Path(path)
        # Through an open file: np.savez would add ".npz" to a temporary name without it.
        with atomic_path(path) as tmp, naming_the_file(path), open(tmp, "wb") as file:
            np.savez_compressed(file, data=self.data, resolution=self.resolution, origin=np.asarray(self.origin))

    @classmethod
    def load(cls, path: str | Path) -> "GridMap":
        path = Path(path)
        try:
            with np.load(path) as npz:
                return cls(npz["data"].astype(np.int8), float(npz["resolution"]), tuple(map(float, npz["origin"])))
        except FileNotFoundError:
            raise InputError(f"grid map file {path} does not exist") from None
        except (KeyError, ValueError, OSError, EOFError, zipfile.BadZipFile) as err:  # a truncated or foreign file
            raise InputError(f"grid map file {path} is not a longslam grid (.npz with data, resolution, origin): {err}") from None

    def describe(self) -> str:
        return json.dumps({"shape": list(self.shape), "resolution": self.resolution, "origin": list(self.origin)})
