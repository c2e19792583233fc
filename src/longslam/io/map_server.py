"""A `GridMap` in ROS map_server's format: `NAME.pgm` beside `NAME.yaml`, what `map_saver`
writes and `map_server` (ROS 1 and Nav2) loads.

The image is a binary PGM (P5), one byte a cell, in trinary mode as map_saver writes it: 0
occupied, 254 free, 205 unknown. Its first row is the top of the map (largest y), so the grid's
rows are flipped; `origin` is the world pose of the lower-left pixel's corner, [x, y, yaw].
The thresholds are map_saver's (occupied_thresh 0.65, free_thresh 0.196): with negate 0 a
pixel's occupancy is (255 - value) / 255, so 0 -> 1.0 (occupied), 254 -> 0.004 (free) and
205 -> 0.19608, just above free_thresh (unknown).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.core.gridmap import GridMap
from longslam.io.atomic import atomic_path, naming_the_file

PGM_OCCUPIED, PGM_FREE, PGM_UNKNOWN = 0, 254, 205
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196


def grid_pixels(grid: GridMap) -> np.ndarray:
    """The PGM's pixels (rows top to bottom) for the grid's cells, by map_saver's trinary rule:
    occupancy >= 65 occupied, 0 to 19 free, anything else (-1, a probability between) unknown."""
    data = np.asarray(grid.data).astype(np.int16)
    pixels = np.full(data.shape, PGM_UNKNOWN, dtype=np.uint8)
    pixels[(data >= 0) & (data < 20)] = PGM_FREE
    pixels[data >= 65] = PGM_OCCUPIED
    return np.ascontiguousarray(pixels[::-1])


def map_yaml(image_name: str, grid: GridMap) -> str:
    """The map's YAML text: map_server's keys, in map_saver's order."""
    x, y = (float(v) for v in grid.origin)
    return (
        f"image: {image_name}\n"
        f"mode: trinary\n"
        f"resolution: {float(grid.resolution)!r}\n"
        f"origin: [{x!r}, {y!r}, 0.0]\n"
        f"negate: 0\n"
        f"occupied_thresh: {OCCUPIED_THRESH}\n"
        f"free_thresh: {FREE_THRESH}\n"
    )


def write_map_server(grid: GridMap, yaml_path: str | Path) -> tuple[Path, Path]:
    """Write `grid` as YAML_PATH (.yaml) and the .pgm of the same name beside it, each through a
    temporary name. Returns (pgm, yaml)."""
    yaml_path = Path(yaml_path)
    if yaml_path.suffix != ".yaml":
        raise InputError(f"map file {yaml_path}: expected a name ending in .yaml")
    pgm_path = yaml_path.with_suffix(".pgm")
    pixels = grid_pixels(grid)
    rows, cols = pixels.shape
    header = f"P5\n# longslam occupancy grid, resolution {float(grid.resolution)!r} m\n{cols} {rows}\n255\n".encode()
    with atomic_path(pgm_path) as tmp, naming_the_file(pgm_path):
        Path(tmp).write_bytes(header + pixels.tobytes())
    with atomic_path(yaml_path) as tmp, naming_the_file(yaml_path):
        Path(tmp).write_text(map_yaml(pgm_path.name, grid), encoding="utf-8")
    return pgm_path, yaml_path
