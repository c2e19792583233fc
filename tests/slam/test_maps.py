"""Every method's written 3D map (map.ply) against the world it was made in."""

import json

import numpy as np
import open3d as o3d
import pytest
from scipy import ndimage

from longslam.core.gridmap import OCCUPIED
from longslam.run.scored_run import run_named
from longslam.sim.camera import CameraSettings
from longslam.sim.routes import Route
from longslam.slam.catalog import BUILTIN, default_method_names
from longslam.world import get_world

pytestmark = pytest.mark.slow  # runs every method end to end on a rendered route

CAMERA = CameraSettings(width=160, height=120)
ROUTE = Route("map-check", "university", ((20.0, 31.25), (26.0, 31.25), "junction_a"))
WALL_HEIGHT = 3.0  # the university's floor-to-ceiling height
TOLERANCE = 0.15  # m: voxel filtering and depth quantisation


@pytest.fixture(scope="module")
def sequence(rendered):
    # No noise: a correct map must then lie on the world's walls.
    return rendered(ROUTE, "none", 0, CAMERA)


# longslam's own methods (a plugin may build no map), but `command`, which runs a program it is given
@pytest.mark.parametrize("method", [m for m in BUILTIN if m in default_method_names()])
def test_written_map_lies_in_the_world(sequence, tmp_path, method):
    out = tmp_path / "run"
    run_named(method, sequence, out, progress=False)
    database = json.loads((out / "stats.json").read_text())["method_stats"].get("database")
    assert database in (None, str(out / "memory.db"))  # the final path, not the temporary one
    if not (out / "map.ply").is_file():
        assert method == "odometry", f"{method} wrote no map.ply"
        return
    points = np.asarray(o3d.io.read_point_cloud(str(out / "map.ply")).points)
    assert len(points) > 100
    world = get_world("university")
    height = points[:, 2] - world.floor_z
    inside = (height > -TOLERANCE) & (height < WALL_HEIGHT + TOLERANCE)
    assert inside.mean() > 0.99, f"{method}: map.ply z spans {height.min():.2f}..{height.max():.2f} m above the floor"

    # Between floor and ceiling, the map is walls and furniture: near the true occupied cells.
    band = points[(height > 0.3) & (height < 2.7)]
    assert len(band) > 50
    grid = world.occupancy
    distance = ndimage.distance_transform_edt(grid.data != OCCUPIED) * grid.resolution
    cells = grid.world_to_cell(band[:, :2])
    rows = np.clip(cells[:, 0], 0, grid.shape[0] - 1)
    cols = np.clip(cells[:, 1], 0, grid.shape[1] - 1)
    near = distance[rows, cols] < 0.25
    assert near.mean() > 0.9, f"{method}: only {near.mean():.0%} of map.ply's points lie within 0.25 m of a wall"
