"""The occupancy grid in ROS map_server's format (grid.pgm + grid.yaml) beside grid.npz, read back
as map_server reads it: Pillow for the image, a YAML parser for the rest, map_server's trinary rule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from helpers.tiny_sequences import write_tiny_sequence
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.io.map_server import write_map_server
from longslam.run.scored_run import run_named
from longslam.io.grid_files import read_grid


def load_like_map_server(yaml_path: Path) -> tuple[dict, np.ndarray]:
    """The map's YAML and its cells as map_server makes them (row 0 at the origin, -1/0/100),
    following map_server's loader: occupancy = (255 - pixel) / 255 with negate 0."""
    meta = yaml.safe_load(yaml_path.read_text())
    image = Image.open(yaml_path.parent / meta["image"])
    assert image.mode == "L"  # one 8-bit channel
    pixels = np.asarray(image)
    p = (255.0 - pixels) / 255.0 if meta["negate"] == 0 else pixels / 255.0
    cells = np.full(p.shape, UNKNOWN, dtype=np.int8)
    cells[p > meta["occupied_thresh"]] = OCCUPIED
    cells[p < meta["free_thresh"]] = FREE
    return meta, cells[::-1]  # the image's first row is the map's top


def test_a_grid_as_map_server_reads_it(tmp_path):
    data = np.full((3, 5), UNKNOWN, dtype=np.int8)
    data[0, :] = FREE
    data[1, 4] = OCCUPIED
    data[2, 0] = OCCUPIED  # top-left in the image
    grid = GridMap(data, 0.05, (-1.25, 2.5))
    pgm, yml = write_map_server(grid, tmp_path / "grid.yaml")
    assert (pgm.name, yml.name) == ("grid.pgm", "grid.yaml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid.pgm", "grid.yaml"]  # no partial left
    meta, cells = load_like_map_server(yml)
    assert meta["image"] == "grid.pgm" and meta["mode"] == "trinary"
    assert meta["resolution"] == 0.05 and meta["origin"] == [-1.25, 2.5, 0.0]
    np.testing.assert_array_equal(cells, data)
    # map_saver's own values: 0 occupied, 254 free, 205 unknown; the image's top row is y's last
    pixels = np.asarray(Image.open(pgm))
    assert pixels.shape == (3, 5) and pixels[0, 0] == 0 and pixels[2, 0] == 254 and pixels[1, 0] == 205


def test_a_run_folder_has_the_grid_for_map_server(tmp_path):
    sequence = write_tiny_sequence(tmp_path / "seq", n=20, turn=1.0)[0]
    run_named("keyframe", sequence, tmp_path / "run", {"frontend.mode": "wheel"}, progress=False)
    grid = read_grid(tmp_path / "run" / "grid.npz")
    assert (grid.data == OCCUPIED).any() and (grid.data == FREE).any() and (grid.data == UNKNOWN).any()
    meta, cells = load_like_map_server(tmp_path / "run" / "grid.yaml")
    np.testing.assert_array_equal(cells, grid.data)  # cell for cell
    assert meta["resolution"] == pytest.approx(grid.resolution, rel=0, abs=0)
    assert meta["origin"][:2] == list(grid.origin) and meta["origin"][2] == 0.0
