"""A `GridMap` on disk: `.npz` with its data, resolution and origin."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.core.gridmap import GridMap
from longslam.io.atomic import atomic_path, naming_the_file


def write_grid(grid: GridMap, path: str | Path) -> None:
    """Write as .npz (data, resolution, origin), via a temporary name."""
    path = Path(path)
    # Through an open file: np.savez would add ".npz" to a temporary name without it.
    with atomic_path(path) as tmp, naming_the_file(path), open(tmp, "wb") as file:
        np.savez_compressed(file, data=grid.data, resolution=grid.resolution, origin=np.asarray(grid.origin))


def read_grid(path: str | Path) -> GridMap:
    """The grid written by `write_grid`; InputError naming the file when it is missing or foreign."""
    path = Path(path)
    try:
        with np.load(path) as npz:
            return GridMap(
                npz["data"].astype(np.int8),
                float(npz["resolution"]),
                (float(npz["origin"][0]), float(npz["origin"][1])),
            )
    except FileNotFoundError:
        raise InputError(f"grid map file {path} does not exist") from None
    except (KeyError, ValueError, OSError, EOFError, zipfile.BadZipFile) as err:  # a truncated or foreign file
        raise InputError(
            f"grid map file {path} is not a longslam grid (.npz with data, resolution, origin): {err}"
        ) from None
