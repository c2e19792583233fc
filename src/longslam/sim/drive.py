"""From a route to ground truth: plan the paths, drive them, and place the camera."""

from __future__ import annotations

import logging

import numpy as np

from longslam.core.geometry import camera_poses_from_planar
from longslam.core.trajectory import Trajectory
from longslam.sim.follower import DrivenPath, FollowerSettings, follow_paths
from longslam.sim.navigation import NavigationGrid
from longslam.sim.routes import Route
from longslam.world.model import World

log = logging.getLogger(__name__)
# A route of more legs than this takes long enough to plan and drive (demo-x1000: some 7,000
# legs, minutes) that it is announced and shown a bar, not left silent.
LONG_ROUTE_LEGS = 200


def drive_route(
    world: World,
    route: Route,
    follower: FollowerSettings = FollowerSettings(),
    robot_radius: float = 0.2,
) -> DrivenPath:
    """The robot's true planar path along the route's waypoints, one pose per camera frame."""
    nav = NavigationGrid(world.occupancy, robot_radius=robot_radius)
    waypoints = route.resolve(world.places)
    labels = [
        f"route {route.name!r} waypoint {i}" + (f" {given!r}" if isinstance(given, str) else "")
        for i, given in enumerate(route.waypoints)
    ]
    for wp, label in zip(waypoints, labels):
        nav.check_waypoint(wp, label)
    nav.check_reachable(waypoints, labels)
    legs = list(zip(waypoints[:-1], waypoints[1:]))
    long_route = len(legs) > LONG_ROUTE_LEGS
    if long_route:
        log.warning(f"note: route {route.name}: planning and driving its {len(legs)} legs takes a while")
    # A route driven N times over has its legs N times: each distinct leg is planned once.
    planned: dict[tuple, np.ndarray] = {}
    paths = []
    for a, b in legs:
        key = (tuple(map(float, a)), tuple(map(float, b)))
        if key not in planned:
            planned[key] = nav.shortest_path(a, b)
        paths.append(planned[key])
    return follow_paths(paths, follower, progress=long_route)


def camera_trajectory(
    timestamps: np.ndarray, xyyaw: np.ndarray, camera_height: float, floor_z: float = 0.0, source: str = ""
) -> Trajectory:
    """Camera-in-world poses for robot base poses on the floor."""
    return Trajectory(timestamps, camera_poses_from_planar(xyyaw, camera_height, floor_z), source=source)
