"""What a study needs before its runs: each route rendered once, and the ground truth kept in DIR.

The rendered frames live in the rendering cache (`longslam.sim.simulate`); the study folder keeps
what the evaluation and the report need without the cache: per route its ground-truth camera
trajectory, waypoints and the mask of walls the camera could see, and per world its ground-truth
occupancy grid.

    DIR/worlds/<world>.npz               ground-truth occupancy (GridMap); a mesh world's name
                                         is its file's stem and a hash of its content
    DIR/routes/<route>/groundtruth.txt   true camera trajectory (TUM)
    DIR/routes/<route>/route.json        waypoints (x, y), length, frames
    DIR/routes/<route>/observed.npy      occupied cells the camera could see (for map recall)

A study with named cameras ([cameras.NAME]) keeps these per camera, in DIR/routes/<route>/<camera>/:
the true camera trajectory depends on the camera's height, the walls it sees on its field of view
and depth range.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from longslam.core.gridmap import GridMap
from longslam.core.trajectory import Trajectory
from longslam.eval.map_quality import observed_walls
from longslam.io.atomic import atomic_path, write_text_atomic
from longslam.io.grid_files import read_grid, write_grid
from longslam.io.trajectory_files import read_tum, write_tum
from longslam.sim.camera import CameraSettings
from longslam.sim.drive import camera_trajectory, drive_route
from longslam.sim.follower import FollowerSettings
from longslam.sim.routes import Route
from longslam.sim.simulate import cache_key, cache_root, rendered_sequence


@contextlib.contextmanager
def _file_lock(path: Path) -> Iterator[None]:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def render_once(
    route: Route,
    camera: CameraSettings,
    follower: FollowerSettings,
    progress: bool = False,
) -> Path:
    """`rendered_sequence` under a lock in the cache, so that processes on one machine that
    need the same route at once render it once (the others wait and reuse it)."""
    root = cache_root()
    lock = root / f".{cache_key(route, camera, follower)}.lock"
    with _file_lock(lock):
        return rendered_sequence(route, camera, follower, root=root, progress=progress)


@dataclass(frozen=True)
class RouteData:
    """A route's ground truth as kept in the study folder."""

    name: str
    truth: Trajectory
    waypoints: np.ndarray  # (K, 2) x, y
    length_m: float
    observed: np.ndarray  # bool mask over the world's occupancy grid


def world_grid_path(out: Path, world: str) -> Path:
    """The grid of a world (a reference): by name, or a mesh's stem and content hash."""
    from longslam.world import world_key

    return Path(out) / "worlds" / f"{world_key(world)}.npz"


def route_dir(out: Path, route: str, camera_name: str = "") -> Path:
    """The route's ground truth in the study folder; per camera for a named camera."""
    folder = Path(out) / "routes" / route
    return folder / camera_name if camera_name else folder


def prepare_route(
    out: Path, route: Route, camera: CameraSettings, follower: FollowerSettings, camera_name: str = ""
) -> None:
    """Write the route's ground truth and its world's occupancy into the study folder (once)."""
    from longslam.world import load_world

    folder = route_dir(out, route.name, camera_name)
    grid_path = world_grid_path(out, route.world)
    info_path = folder / "route.json"
    settings = {"camera": asdict(camera), "follower": asdict(follower)}
    if info_path.is_file() and grid_path.is_file():
        info = json.loads(info_path.read_text(encoding="utf-8"))
        if info.get("settings") == json.loads(json.dumps(settings)) and info.get("waypoints_given") == _waypoints_json(
            route
        ):
            return
    world = load_world(route.world)
    if not grid_path.is_file():
        grid_path.parent.mkdir(parents=True, exist_ok=True)
        write_grid(world.occupancy, grid_path)
    driven = drive_route(world, route, follower)
    truth = camera_trajectory(
        driven.timestamps, driven.xyyaw, camera.camera_height, world.floor_z, source="ground truth"
    )
    folder.mkdir(parents=True, exist_ok=True)
    write_tum(folder / "groundtruth.txt", truth)
    observed = observed_walls(world.occupancy, driven.xyyaw, camera.hfov_deg, camera.max_depth)
    with atomic_path(folder / "observed.npy") as tmp:
        with open(tmp, "wb") as handle:
            np.save(handle, observed)
    info = {
        "route": route.name,
        "world": route.world,
        "waypoints_given": _waypoints_json(route),
        "waypoints": [list(map(float, wp)) for wp in route.resolve(world.places)],
        "length_m": driven.length,
        "frames": len(truth),
        "settings": settings,
    }
    write_text_atomic(info_path, json.dumps(info, indent=2) + "\n")


def _waypoints_json(route: Route) -> list:
    return route.waypoints_json()


def load_route_data(out: Path, route: str, camera_name: str = "") -> RouteData:
    folder = route_dir(out, route, camera_name)
    info = json.loads((folder / "route.json").read_text(encoding="utf-8"))
    return RouteData(
        name=route,
        truth=read_tum(folder / "groundtruth.txt"),
        waypoints=np.asarray(info["waypoints"], dtype=np.float64).reshape(-1, 2),
        length_m=float(info["length_m"]),
        observed=np.load(folder / "observed.npy"),
    )


def load_world_grid(out: Path, world: str) -> GridMap:
    return read_grid(world_grid_path(out, world))


def clean_partials(folder: Path) -> int:
    """Remove temporary folders left by runs that were killed; returns how many."""
    import shutil

    removed = 0
    if folder.is_dir():
        for path in folder.rglob(".*.partial-*"):
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    os.unlink(path)
            removed += 1
    return removed


def check_routes(config) -> None:
    """Drive every route of a study on its world (a second or two each), so that a route through
    a wall or to an unknown place is refused before anything is written."""
    from longslam.core.errors import InputError
    from longslam.sim.simulate import check_camera_in_world
    from longslam.world import load_world

    for route in config.routes:
        world = load_world(route.world)
        for name, camera in config.camera_axis():
            try:
                check_camera_in_world(world, camera)
            except InputError as err:  # name the study file's table the height came from
                raise InputError(
                    f"study file {config.source}: {f'cameras.{name}' if name else 'camera'}.camera_height: {err}"
                ) from None
        drive_route(world, route, config.follower)


def check_out_folder(out: Path) -> None:
    """A study folder must be a folder (new or existing) that can be written."""
    from longslam.io.paths import check_output_folder

    check_output_folder(out, "study folder")
